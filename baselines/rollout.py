"""The one episode loop: a controller on an environment, one episode or many rows at once,
and the figures of every episode (:class:`dss14_env.core.results.EpisodeFigures`).

The bench's runner (:mod:`dss14_env.bench.runner`) and the robustness campaign run their
episodes through :func:`run_rows` (or :func:`run_episode`), and so does the agents'
evaluation (:func:`dss14_env.agents.evaluation.run_task`).

**Episodes.**  Episode ``seed`` of a scenario is the environment reset with that seed, so every
controller sees the same start, wind direction, trajectory and gust realisation for the same
seed (the environment draws nothing that depends on the actions).  A controller that acts on
batches (``batchable``: :meth:`~dss14_env.baselines.base.Controller.act_batch` on ``(N, 12)``
observations) runs all its episodes of a scenario at once, one row per seed, through the numpy
vector environment :class:`dss14_env.envs.vector.DSS14VectorEnv` reset with the list of seeds
(row i is the episode of a single environment reset with seed i); any other controller (the
MPC) runs its episodes one by one on :class:`dss14_env.envs.env.DSS14Env`, on the first
``sequential_seeds`` of the seeds (the vector environment equals the single one up to
floating-point rounding, which the quantised encoder can turn into different last bits of the
trajectory, never into a different episode).  Every episode runs exactly the scenario's number
of steps unless it terminates (1° error bound, travel limits); the rows of a batch that
terminated are masked from then on.  Controllers are built once per scenario by a factory that
gets the (single) environment (they read its interface, never its plant).  A controller with
``set_scenario(speed, direction)`` / ``set_scenario_batch(speeds, directions)`` (the yardstick,
an oracle of the wind) is told the episode's wind from the reset info.

**Metrics per episode** (:func:`episode_metrics`; angles in mdeg, after the scenario's warm-up):

* ``servo_error_mdeg`` per axis (az, el): ``three_sigma`` (3 x standard deviation about the
  episode's mean, the report's Table 4 quantity, from the true servo error at the encoders:
  command - axis angle, unquantised), ``rms`` (mean included), ``max`` (largest magnitude),
  ``mean``;
* ``pointing_error_mdeg`` (el, xel): the same for the dish's true pointing error, the
  environment's ``pointing_error_*_mdeg`` (the command minus the structure's pointing angle,
  deformation included);
* ``cost_per_step`` (mean negated reward), ``rate_command_deg_s`` (per axis ``rms``, ``peak``
  and largest change per second ``peak_accel_deg_s2`` of the applied command), ``limit_hits``
  (steps the limiter clipped the rate or its change), ``controller_time_ms`` (``median``,
  ``p95``, ``max`` wall time of one decision: one ``act()``, or one ``act_batch()`` divided by
  its rows), ``step`` (scenarios with a commanded move, a step or a slew:
  :func:`move_response`'s overshoot, settling into the 2 % band, peak error and rms after
  settling); ``smoothness`` (:mod:`dss14_env.core.smoothness`, over the whole
  episode): ``accel_limit_hits_pct``, the periods the limiter clipped the command's change in %
  of the periods run, and ``command_change_hf_pct`` per axis, the share of the variance of the
  rate command's first difference above 5 Hz, %;
* health: ``terminated``, ``failures`` (the controller raised; the episode ends there),
  ``fallbacks`` (MPC solves replaced by the fallback law, ``info["n_fallbacks"]``) and
  ``fallback_log`` (the solver status of each fallback, ``info["fallbacks"]``, when the
  controller gives it).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dss14_env.baselines.base import Controller
from dss14_env.core.results import POINTING_AXES, EpisodeFigures, ErrorStats
from dss14_env.core.smoothness import high_frequency_share, limit_hit_pct
from dss14_env.core.units import AXES
from dss14_env.envs.core import OBS

#: the environment's scenario kinds (``scenario``) whose command is one move, scored by its
#: response when :func:`run_rows` is not told otherwise
MOVE_SCENARIOS = ("step", "slew")


def step_response(t: np.ndarray, theta: np.ndarray, size: float, t_step: float,
                  band: float = 0.02) -> dict[str, float]:
    """Overshoot (%) and settling time (s, ``band`` of the step) of one axis.

    :param t: times, s
    :param theta: position relative to the start (same unit as ``size``)
    :param size: step size (signed)
    :param t_step: time of the step, s
    """
    m = t >= t_step
    if size == 0 or not np.any(m):  # no step, or the episode ended before it
        return {"overshoot_pct": math.nan, "settling_time_s": math.nan}
    y = np.asarray(theta, float)[m] / size
    over = max(0.0, float(y.max()) - 1.0) * 100.0
    outside = np.nonzero(np.abs(y - 1.0) > band)[0]
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == y.size - 1:
        settle = math.inf
    else:
        settle = float(t[m][outside[-1] + 1] - t_step)
    return {"overshoot_pct": over, "settling_time_s": settle}


def move_response(t: np.ndarray, e: np.ndarray, c: np.ndarray, p: np.ndarray, scored: np.ndarray,
                  band: float = 0.02) -> dict[str, Any]:
    """The response to the commanded move of an episode (a step or a slew): the move of each
    axis is the command's change from the first to the last sample, ending at the command's
    last change.

    Per moved axis (az, el): ``overshoot_pct``, the largest excursion past the target after the
    move's end in % of the move; ``settling_time_s``, from the move's end until the servo error
    stays within ``band`` of the move (``inf``: not settled at the end; 0: never outside);
    ``peak_error_mdeg``, the largest |servo error| in the scored window; ``settled_rms_mdeg``,
    the servo error's rms (mean included) after settling (NaN: not settled, or no sample left).
    Under ``pointing``, per pointing axis (el, xel): ``peak_error_mdeg`` and
    ``settled_rms_mdeg`` of the dish's pointing error, after the last moved axis settled.
    Empty when the command did not move (e.g. the episode ended before the step); overshoot,
    settling and the rms after settling NaN when it still moved at the episode's end.

    :param t: times, s
    :param e: true servo errors (n, 2), mdeg
    :param c: commands (n, 2), deg
    :param p: pointing errors (n, 2), mdeg
    :param scored: the samples after the warm-up (n,)
    :param band: the settling band, a share of the move
    """
    out: dict[str, Any] = {}
    settled_at: list[float] = []
    for i, ax in enumerate(AXES):
        size = float(c[-1, i] - c[0, i]) * 1e3 if len(c) else 0.0  # mdeg
        changed = np.nonzero(np.diff(c[:, i]))[0]
        if size == 0.0 or changed.size == 0:
            continue
        t_end = float(t[changed[-1] + 1])
        if changed[-1] + 2 == len(t):  # still moving at the episode's end: nothing settled
            r = {"overshoot_pct": math.nan, "settling_time_s": math.nan}
        else:
            r = step_response(t, c[:, i] * 1e3 - e[:, i] - c[0, i] * 1e3, size, t_end, band)
        settle = t_end + r["settling_time_s"]
        after = t >= settle
        r["peak_error_mdeg"] = float(np.max(np.abs(e[scored, i]))) if np.any(scored) else math.nan
        r["settled_rms_mdeg"] = float(np.sqrt(np.mean(e[after, i] ** 2))) if np.any(after) else math.nan
        out[ax] = r
        settled_at.append(settle)
    if out:
        after = t >= max(settled_at)
        out["pointing"] = {ax: {"peak_error_mdeg": float(np.max(np.abs(p[scored, i]))) if np.any(scored)
                                else math.nan,
                                "settled_rms_mdeg": float(np.sqrt(np.mean(p[after, i] ** 2)))
                                if np.any(after) else math.nan}
                           for i, ax in enumerate(POINTING_AXES)}
    return out


def episode_metrics(rec: Mapping[str, np.ndarray], dt: float, warmup_s: float, move: bool,
                    limits: Mapping[str, float]) -> dict[str, Any]:
    """Metrics of one recorded episode (see the module docstring).

    :param rec: arrays ``e`` (n, 2) true servo errors (mdeg), ``p`` (n, 2) pointing errors
        (mdeg), ``c`` (n, 2) commands relative to the start (deg), ``r`` (n, 2) applied rate
        commands (deg/s), ``cost`` (n,), ``hits`` (n, 2) rate/accel limiter flags, ``t_ctrl``
        (n,) decision times (s)
    :param dt: control period, s
    :param warmup_s: left out of the error statistics, s
    :param move: score the response to the commanded move (:func:`move_response`, under
        ``step``)
    :param limits: ``rate_deg_s`` and ``accel_deg_s2`` of the limiter (for the record)
    """
    return episode_figures(rec, dt, warmup_s, move, limits).to_dict()


def episode_figures(rec: Mapping[str, np.ndarray], dt: float, warmup_s: float, move: bool,
                    limits: Mapping[str, float]) -> EpisodeFigures:
    """The typed figures of one recorded episode (:func:`episode_metrics`' arguments)."""
    n = len(rec["cost"])
    t = (np.arange(n) + 1) * dt
    w = t > warmup_s
    e, p = rec["e"], rec["p"]
    errors = {"servo_error_mdeg": {ax: ErrorStats.of(e[w, i]) for i, ax in enumerate(AXES)},
              "pointing_error_mdeg": {ax: ErrorStats.of(p[w, i]) for i, ax in enumerate(POINTING_AXES)}}
    r = rec["r"] if n else np.zeros((1, 2))
    dr = np.abs(np.diff(r, axis=0)) / dt if n > 1 else np.zeros((0, 2))
    rate = {ax: {"rms": float(np.sqrt(np.mean(r[:, i] ** 2))), "peak": float(np.max(np.abs(r[:, i]))),
                 "peak_accel_deg_s2": float(dr[:, i].max()) if dr.size else 0.0}
            for i, ax in enumerate(AXES)}
    tc = np.asarray(rec["t_ctrl"]) * 1e3 if len(rec["t_ctrl"]) else np.zeros(1)
    times = {"median": float(np.median(tc)), "p95": float(np.percentile(tc, 95)), "max": float(tc.max())}
    step_fig = move_response(t, e, rec["c"], p, w) if move else None
    return EpisodeFigures(
        n_steps=int(n), seconds=float(np.count_nonzero(w) * dt), errors=errors,
        cost_per_step=float(np.mean(rec["cost"][w])) if np.any(w) else math.nan,
        rate_command_deg_s=rate, limits=dict(limits),
        limit_hits={"rate": int(rec["hits"][:, 0].sum()), "accel": int(rec["hits"][:, 1].sum())},
        controller_time_ms=times, step=step_fig or None,
        smoothness={"accel_limit_hits_pct": limit_hit_pct(rec["hits"][:, 1]),
                    "command_change_hf_pct": {ax: 100.0 * high_frequency_share(rec["r"][:, i], dt)
                                              for i, ax in enumerate(AXES)}})


# ------------------------------------------------------------------------- controllers
class SequentialDriver:
    """A controller driven one episode at a time on the single environment."""

    batched = False

    def __init__(self, ctrl: Controller) -> None:
        self.ctrl = ctrl

    def reset(self, seeds: Sequence[int], info: Mapping[str, Any]) -> None:
        if hasattr(self.ctrl, "set_scenario"):
            self.ctrl.set_scenario(float(info["wind_speed_mps"]), float(info["wind_direction_rad"]))
        self.ctrl.reset(int(seeds[0]))

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.ctrl.act(obs)

    def restart(self, mask: np.ndarray) -> None:  # one row: the episode ends instead
        pass

    def row_info(self, n: int) -> list[dict[str, Any]]:
        return [dict(self.ctrl.info)]


class BatchDriver:
    """A controller with the batch interface (``batchable``) on the vector environment."""

    batched = True

    def __init__(self, ctrl: Controller) -> None:
        self.ctrl = ctrl

    def reset(self, seeds: Sequence[int], info: Mapping[str, Any]) -> None:
        self.ctrl.reset_batch(len(seeds), seeds=[int(s) for s in seeds])
        if hasattr(self.ctrl, "set_scenario_batch"):  # after reset_batch: one wind per row
            self.ctrl.set_scenario_batch(np.asarray(info["wind_speed_mps"], float),
                                         np.asarray(info["wind_direction_rad"], float))

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.ctrl.act_batch(obs)

    def restart(self, mask: np.ndarray) -> None:
        self.ctrl.restart(mask)

    def row_info(self, n: int) -> list[dict[str, Any]]:
        info = getattr(self.ctrl, "info_batch", None) or {}
        rows: list[dict[str, Any]] = [{} for _ in range(n)]
        for key, v in info.items():
            if isinstance(v, np.ndarray) and v.shape[:1] == (n,):
                for i in range(n):
                    rows[i][key] = v[i]
            elif isinstance(v, (list, tuple)) and len(v) == n:
                for i in range(n):
                    rows[i][key] = v[i]
        return rows


def batch_driver(ctrl: Controller) -> BatchDriver | None:
    """How the runner drives ``ctrl`` on the vector environment (its ``batchable`` interface),
    or None: one episode at a time.
    """
    return BatchDriver(ctrl) if getattr(ctrl, "batchable", False) else None



def _fallback_record(info: Mapping[str, Any]) -> dict[str, Any]:
    """Fallback count and, when the controller gives them, each fallback's step and status."""
    out: dict[str, Any] = {"fallbacks": int(info.get("n_fallbacks", 0) or 0)}
    log = info.get("fallbacks")
    if isinstance(log, (list, tuple)):
        out["fallback_log"] = [{"step": int(f["step"]), "status": str(f["status"])} for f in log]
        out["fallbacks"] = max(out["fallbacks"], len(log))
    elif isinstance(info.get("fallback_statuses"), Mapping):
        out["fallback_statuses"] = {str(k): int(v) for k, v in info["fallback_statuses"].items()}
    return out


def run_rows(driver: Any, env: Any, seeds: Sequence[int], steps: int, warmup_s: float = 0.0,
             record: bool = False, reseed: bool = True, move: bool | None = None) -> list[dict[str, Any]]:
    """Episodes ``seeds`` of one controller: rows of a vector environment (batched driver) or
    one episode on a single environment (sequential driver, one seed).

    :param driver: :func:`batch_driver`'s result on a vector env with ``len(seeds)`` rows, or
        the sequential driver on a single env
    :param env: the environment
    :param seeds: one seed per row
    :param steps: control periods per episode
    :param warmup_s: left out of the error statistics, s
    :param record: keep the first row's time histories under ``"trace"``
    :param reseed: reset the environment with ``seeds`` (default); False continues its
        generators (the next episodes after a seeded reset; ``seeds`` then only label the rows)
    :param move: score the response to the commanded move (:func:`move_response`; the bench
        passes its catalog's ``move`` group); None: in the environment's scenario kinds of
        :data:`MOVE_SCENARIOS`
    :return: one :func:`episode_metrics` dict per seed, with ``seed``, ``terminated``,
        ``failures``, ``failure``, ``fallbacks`` (and ``fallback_log``), the episode's wind
        and ``batch_rows``
    """
    n = len(seeds)
    cfg = env.unwrapped.config if hasattr(env, "unwrapped") else env.config
    if reseed:
        obs, info = env.reset(seed=[int(s) for s in seeds] if driver.batched else int(seeds[0]))
    else:
        obs, info = env.reset()
    wind = (np.broadcast_to(np.asarray(info["wind_speed_mps"], float), (n,)).copy(),
            np.broadcast_to(np.asarray(info["wind_direction_rad"], float), (n,)).copy())
    driver.reset(seeds, info)
    E = np.zeros((steps, n, 2))
    P = np.zeros((steps, n, 2))
    Cm = np.zeros((steps, n, 2))
    R = np.zeros((steps, n, 2))
    cost = np.zeros((steps, n))
    hits = np.zeros((steps, n, 2), bool)
    tc = np.zeros(steps)
    enc = np.zeros((steps, 2)) if record else None
    length = np.full(n, steps)
    terminated = np.zeros(n, bool)
    alive = np.ones(n, bool)
    pending = np.zeros(n, bool)  # rows the vector env resets at the next step
    failure = None
    for k in range(steps):
        t0 = time.perf_counter()
        try:
            a = driver.act(obs)
        except Exception as exc:  # noqa: BLE001 - a controller failure is a result, not a crash
            failure = f"{type(exc).__name__}: {exc}"
            length[alive] = k
            break
        tc[k] = (time.perf_counter() - t0) / n
        obs, rew, term, _, info = env.step(a)
        o = obs.reshape(n, -1)  # 12 entries, 14 with the monopulse sensor
        E[k, :, 0], E[k, :, 1] = info["servo_error_az_mdeg"], info["servo_error_el_mdeg"]
        P[k, :, 0], P[k, :, 1] = info["pointing_error_el_mdeg"], info["pointing_error_xel_mdeg"]
        Cm[k] = o[:, OBS.command]
        R[k, :, 0], R[k, :, 1] = info["rate_command_az_deg_s"], info["rate_command_el_deg_s"]
        cost[k] = -np.asarray(rew)
        hits[k, :, 0], hits[k, :, 1] = info["rate_limited"], info["accel_limited"]
        if enc is not None:
            enc[k] = o[0, OBS.encoder]
        if pending.any():
            driver.restart(pending)
            pending[:] = False
        term = np.asarray(term, bool).reshape(n)
        if term.any():
            ended = term & alive
            length[ended] = k + 1
            terminated |= ended
            alive &= ~term
            pending = term.copy()
            if not alive.any():
                break
    rows = driver.row_info(n)
    move = cfg.scenario in MOVE_SCENARIOS if move is None else bool(move)
    limits = {"rate_deg_s": cfg.rate_limit_deg_s, "accel_deg_s2": cfg.accel_limit_deg_s2}
    out = []
    for i, seed in enumerate(seeds):
        L = int(length[i])
        rec = {"e": E[:L, i], "p": P[:L, i], "c": Cm[:L, i], "r": R[:L, i], "cost": cost[:L, i],
               "hits": hits[:L, i], "t_ctrl": tc[:max(L, 1)]}
        m = episode_metrics(rec, cfg.dt, warmup_s, move, limits)
        m.update({"seed": int(seed), "terminated": bool(terminated[i]),
                  "failures": int(failure is not None), "failure": failure,
                  **_fallback_record(rows[i]),
                  "wind_speed_mps": float(wind[0][i]), "wind_direction_rad": float(wind[1][i]),
                  "batch_rows": n})
        if enc is not None and i == 0:
            m["trace"] = {"t": (np.arange(L) + 1) * cfg.dt, "servo_error_mdeg": E[:L, 0].copy(),
                          "pointing_error_mdeg": P[:L, 0].copy(), "command_deg": Cm[:L, 0].copy(),
                          "encoder_deg": enc[:L].copy(), "rate_command_deg_s": R[:L, 0].copy()}
        out.append(m)
    return out


def run_episode(ctrl: Controller, env: Any, seed: int, steps: int, warmup_s: float = 0.0,
                record: bool = False, move: bool | None = None) -> dict[str, Any]:
    """One episode of one controller on a single environment (:func:`run_rows`, one row)."""
    return run_rows(SequentialDriver(ctrl), env, [seed], steps, warmup_s, record, move=move)[0]



__all__ = ["BatchDriver", "MOVE_SCENARIOS", "SequentialDriver", "batch_driver", "episode_figures",
           "episode_metrics", "move_response", "run_episode", "run_rows", "step_response"]
