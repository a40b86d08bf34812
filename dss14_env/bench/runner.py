"""The one runner that scores every controller the same way: controller x scenario x seeds.

>>> res = run(["pi_kp1"], ["hold_side"], seeds=[0, 1], steps=300)
>>> s = res["summary"]["pi_kp1"]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
>>> 0.5 < s["value"] < 5.0, s["n_episodes"], len(s["ci95"])  # mdeg; Table 4: 2.1 (50 km/h side)
(True, 2, 2)

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
  its rows), ``step`` (scenarios with a command step: ``overshoot_pct``, ``settling_time_s``
  into the 2 % band);
* health: ``terminated``, ``failures`` (the controller raised; the episode ends there),
  ``fallbacks`` (MPC solves replaced by the fallback law, ``info["n_fallbacks"]``) and
  ``fallback_log`` (the solver status of each fallback, ``info["fallbacks"]``, when the
  controller gives it).

**Summary per controller and scenario** (:func:`summarise`): every metric pooled over the
episodes with a 95 % confidence interval, ``{"value", "ci95": [lo, hi], "n_episodes",
"seconds", "median", "min", "max"}`` (``seconds``: the data behind it, warm-ups left out;
``median``, ``min``, ``max``: over the episodes, the spread of single episodes).  Spreads pool
as root mean squares (the pooled 3σ of n equal episodes is ``sqrt(mean(three_sigma_i ** 2))``),
peaks, means, costs and overshoots as means, times as medians; the interval is the percentile
bootstrap over episodes (:func:`dss14_env.core.stats.pooled_estimates`), all metrics of a cell
resampled together from a generator seeded by the cell's name (:func:`cell_rng`), so a rerun
reproduces it.  Ratios (``three_sigma`` per axis): ``vs_reference``, over the reference
controller (default the report's PI, ``pi_kp1``) on the seeds both ran, resampling the pairs
together; ``vs_yardstick``, over the yardstick's analytic expected 3σ
(:func:`dss14_env.baselines.yardstick.expected_performance`) for scenarios with one fixed wind;
each ``{"value", "ci95", "significant", "n_episodes"}``, with ``significant`` False when the
interval contains 1 (None without an interval).
"""

from __future__ import annotations

import math
import time
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from dss14_env.baselines.base import Controller
from dss14_env.bench import catalog
from dss14_env.bench.catalog import SCENARIO_ROWS, ControllerRow, Scenario
from dss14_env.core import stats
from dss14_env.core.units import AXES, KMH
from dss14_env.envs.core import OBS, OBS_SIZE

#: pointing-error axes (elevation and cross-elevation)
POINTING_AXES = ("el", "xel")
#: confidence level of every interval
LEVEL = stats.LEVEL
#: bootstrap resamples per summary cell
N_RESAMPLES = stats.N_RESAMPLES
#: the most rows x steps one vector environment records at once (the time histories of a batch
#: are kept until its metrics are computed); longer lists of seeds run in chunks
MAX_ROW_STEPS = 1_000_000
#: the controller every other is divided by in ``vs_reference``
REFERENCE = "pi_kp1"


#: the benchmark scenarios as the runner runs them, by name (the catalog's rows:
#: :data:`dss14_env.bench.catalog.SCENARIO_ROWS`)
SCENARIOS: Mapping[str, Scenario] = MappingProxyType({r.name: r.scenario() for r in SCENARIO_ROWS})
#: controller factories by name (the catalog's rows, each called with the environment)
CONTROLLERS: Mapping[str, ControllerRow] = catalog.CONTROLLERS


def known_unbatchable(factory: Callable[[Any], Controller]) -> bool:
    """True when the factory is a catalog row that runs one episode at a time (then a scenario
    that gives such controllers no episodes need not build it).
    """
    return isinstance(factory, ControllerRow) and not factory.batchable


#: how each per-episode metric is pooled over episodes (:data:`dss14_env.core.stats.POOLINGS`)
ERROR_POOLING = {"three_sigma": "rms", "rms": "rms", "max": "mean", "mean": "mean"}
RATE_POOLING = {"rms": "rms", "peak": "mean", "peak_accel_deg_s2": "mean"}
STEP_POOLING = {"overshoot_pct": "mean", "settling_time_s": "median"}
TIME_POOLING = {"median": "median", "p95": "median", "max": "median"}


# ------------------------------------------------------------------------- metrics
def _stats(x: np.ndarray) -> dict[str, float]:
    x = np.asarray(x, float)
    if x.size == 0:
        return {"three_sigma": math.nan, "rms": math.nan, "max": math.nan, "mean": math.nan}
    return {"three_sigma": float(3.0 * x.std()), "rms": float(np.sqrt(np.mean(x * x))),
            "max": float(np.max(np.abs(x))), "mean": float(x.mean())}


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


def episode_metrics(rec: Mapping[str, np.ndarray], dt: float, warmup_s: float,
                    step: Mapping[str, Any] | None, limits: Mapping[str, float]) -> dict[str, Any]:
    """Metrics of one recorded episode (see the module docstring).

    :param rec: arrays ``e`` (n, 2) true servo errors (mdeg), ``p`` (n, 2) pointing errors
        (mdeg), ``c`` (n, 2) commands (deg), ``r`` (n, 2) applied rate commands (deg/s),
        ``cost`` (n,), ``hits`` (n, 2) rate/accel limiter flags, ``t_ctrl`` (n,) decision
        times (s)
    :param dt: control period, s
    :param warmup_s: left out of the error statistics, s
    :param step: ``{"size_deg": [az, el], "time_s": t}`` for a step scenario, else None
    :param limits: ``rate_deg_s`` and ``accel_deg_s2`` of the limiter (for the record)
    """
    n = len(rec["cost"])
    t = (np.arange(n) + 1) * dt
    w = t > warmup_s
    e, p = rec["e"], rec["p"]
    out: dict[str, Any] = {
        "n_steps": int(n),
        "seconds": float(np.count_nonzero(w) * dt),
        "servo_error_mdeg": {ax: _stats(e[w, i]) for i, ax in enumerate(AXES)},
        "pointing_error_mdeg": {ax: _stats(p[w, i]) for i, ax in enumerate(POINTING_AXES)},
        "cost_per_step": float(np.mean(rec["cost"][w])) if np.any(w) else math.nan,
    }
    r = rec["r"] if n else np.zeros((1, 2))
    dr = np.abs(np.diff(r, axis=0)) / dt if n > 1 else np.zeros((0, 2))
    out["rate_command_deg_s"] = {ax: {"rms": float(np.sqrt(np.mean(r[:, i] ** 2))),
                                      "peak": float(np.max(np.abs(r[:, i]))),
                                      "peak_accel_deg_s2": float(dr[:, i].max()) if dr.size else 0.0}
                                 for i, ax in enumerate(AXES)}
    out["limits"] = dict(limits)
    out["limit_hits"] = {"rate": int(rec["hits"][:, 0].sum()), "accel": int(rec["hits"][:, 1].sum())}
    tc = np.asarray(rec["t_ctrl"]) * 1e3 if len(rec["t_ctrl"]) else np.zeros(1)
    out["controller_time_ms"] = {"median": float(np.median(tc)), "p95": float(np.percentile(tc, 95)),
                                 "max": float(tc.max())}
    if step is not None:
        theta = rec["c"] * 1e3 - e  # mdeg
        out["step"] = {ax: step_response(t, theta[:, i], step["size_deg"][i] * 1e3, step["time_s"])
                       for i, ax in enumerate(AXES) if step["size_deg"][i] != 0}
    return out


# ------------------------------------------------------------------------- controllers
class _Sequential:
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


class _Batched:
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


def batch_driver(ctrl: Controller) -> _Batched | None:
    """How the runner drives ``ctrl`` on the vector environment (its ``batchable`` interface),
    or None: one episode at a time.
    """
    return _Batched(ctrl) if getattr(ctrl, "batchable", False) else None


# ------------------------------------------------------------------------- running
def _make_env(env_kwargs: Mapping[str, Any]) -> Any:
    from dss14_env.envs.env import DSS14Env
    return DSS14Env(**dict(env_kwargs))


def _make_vector_env(env_kwargs: Mapping[str, Any], n: int) -> Any:
    from dss14_env.envs.vector import DSS14VectorEnv
    return DSS14VectorEnv(num_envs=n, **dict(env_kwargs))


def _resolve_controller(c: Any) -> tuple[str, Callable[[Any], Controller]]:
    if isinstance(c, str):
        if c not in catalog.CONTROLLERS:
            raise ValueError(f"unknown controller {c!r}; known: {sorted(catalog.CONTROLLERS)}")
        return c, catalog.CONTROLLERS[c]
    if isinstance(c, ControllerRow):
        return c.name, c
    if isinstance(c, Controller):
        return c.name, (lambda env, _c=c: _c)
    if isinstance(c, tuple) and len(c) == 2 and isinstance(c[0], str) and callable(c[1]):
        return c[0], c[1]
    raise TypeError(f"a controller must be a name of {sorted(CONTROLLERS)}, a Controller or a "
                    f"(name, factory(env)) pair, got {c!r}")


def _resolve_scenario(s: Any) -> tuple[str, Scenario]:
    if isinstance(s, str):
        if s not in catalog.SCENARIOS:
            raise ValueError(f"unknown scenario {s!r}; known: {sorted(catalog.SCENARIOS)}")
        return s, catalog.SCENARIOS[s].scenario()
    if isinstance(s, tuple) and len(s) == 2 and isinstance(s[1], Scenario):
        return s
    raise TypeError(f"a scenario must be a name of {sorted(SCENARIOS)} or a (name, Scenario) "
                    f"pair, got {s!r}")


def _step_spec(cfg: Any) -> dict[str, Any] | None:
    if cfg.scenario != "step":
        return None
    mask = {"az": (1.0, 0.0), "el": (0.0, 1.0), "both": (1.0, 1.0)}[cfg.step_axes]
    return {"size_deg": [cfg.step_deg * m for m in mask], "time_s": cfg.step_time_s}


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
             record: bool = False) -> list[dict[str, Any]]:
    """Episodes ``seeds`` of one controller: rows of a vector environment (batched driver) or
    one episode on a single environment (sequential driver, one seed).

    :param driver: :func:`batch_driver`'s result on a vector env with ``len(seeds)`` rows, or
        the sequential driver on a single env
    :param env: the environment
    :param seeds: one seed per row
    :param steps: control periods per episode
    :param warmup_s: left out of the error statistics, s
    :param record: keep the first row's time histories under ``"trace"``
    :return: one :func:`episode_metrics` dict per seed, with ``seed``, ``terminated``,
        ``failures``, ``failure``, ``fallbacks`` (and ``fallback_log``), the episode's wind
        and ``batch_rows``
    """
    n = len(seeds)
    cfg = env.unwrapped.config if hasattr(env, "unwrapped") else env.config
    obs, info = env.reset(seed=[int(s) for s in seeds] if driver.batched else int(seeds[0]))
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
        o = obs.reshape(n, OBS_SIZE)
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
    step = _step_spec(cfg)
    limits = {"rate_deg_s": cfg.rate_limit_deg_s, "accel_deg_s2": cfg.accel_limit_deg_s2}
    out = []
    for i, seed in enumerate(seeds):
        L = int(length[i])
        rec = {"e": E[:L, i], "p": P[:L, i], "c": Cm[:L, i], "r": R[:L, i], "cost": cost[:L, i],
               "hits": hits[:L, i], "t_ctrl": tc[:max(L, 1)]}
        m = episode_metrics(rec, cfg.dt, warmup_s, step, limits)
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
                record: bool = False) -> dict[str, Any]:
    """One episode of one controller on a single environment (:func:`run_rows`, one row)."""
    return run_rows(_Sequential(ctrl), env, [seed], steps, warmup_s, record)[0]


# ------------------------------------------------------------------------- summaries
def cell_rng(*names: str, seed: int = 0) -> np.random.Generator:
    """The bootstrap generator of a summary cell: seeded by ``seed`` and the cell's names."""
    return np.random.default_rng([int(seed)] + [zlib.crc32(n.encode()) for n in names])


#: the pooling of every pooled metric by its top-level key: one rule, or one per statistic
POOLING: dict[str, str | dict[str, str]] = {
    "servo_error_mdeg": ERROR_POOLING, "pointing_error_mdeg": ERROR_POOLING, "cost_per_step": "mean",
    "rate_command_deg_s": RATE_POOLING, "limit_hits": "mean", "controller_time_ms": TIME_POOLING,
    "step": STEP_POOLING}


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as ``{"a.b.c": leaf}``."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _pooling(path: str) -> str | None:
    rule = POOLING.get(path.split(".", 1)[0])
    if isinstance(rule, dict):
        return rule.get(path.rsplit(".", 1)[-1])
    return rule


def _columns(episodes: Sequence[Mapping[str, Any]]) -> tuple[dict[str, list[float]], dict[str, str]]:
    """Per-episode values of every pooled metric, keyed by their path, and their pooling
    (NaN where an episode lacks the metric, e.g. a step response on an axis without a step).
    """
    flats = [flatten({k: ep[k] for k in POOLING if k in ep}) for ep in episodes]
    paths: list[str] = []
    for f in flats:
        paths += [p for p in f if p not in paths and _pooling(p) is not None]
    cols = {p: [math.nan if f.get(p) is None else float(f[p]) for f in flats] for p in paths}
    return cols, {p: str(_pooling(p)) for p in paths}


def _cell(est: stats.Estimate, values: Sequence[float], seconds: float) -> dict[str, Any]:
    v = np.asarray(values, float)
    v = v[~np.isnan(v)]
    spread = (float(np.median(v)), float(np.min(v)), float(np.max(v))) if v.size else (math.nan,) * 3
    return {"value": est.value, "ci95": [est.low, est.high], "n_episodes": est.n,
            "seconds": seconds, "median": spread[0], "min": spread[1], "max": spread[2]}


def _nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for path, v in flat.items():
        d = out
        *head, last = path.split(".")
        for h in head:
            d = d.setdefault(h, {})
        d[last] = v
    return out


def summarise(episodes: Sequence[Mapping[str, Any]], rng: np.random.Generator | None = None,
              n_resamples: int = N_RESAMPLES, level: float = LEVEL) -> dict[str, Any]:
    """Every metric of one controller and scenario pooled over its episodes, with its
    confidence interval (see the module docstring).

    :param episodes: :func:`episode_metrics` dicts (with ``seed``)
    :param rng: bootstrap generator, default seeded with 0
    :return: ``n_episodes``, ``seeds``, ``seconds``, the metrics as ``{"value", "ci95",
        "n_episodes", "seconds", "median", "min", "max"}``, ``limit_hits`` (``rate``/``accel`` totals and
        ``per_episode``), ``fallbacks``, ``failures``, ``terminated`` (totals)
    """
    rng = np.random.default_rng(0) if rng is None else rng
    cols, pool = _columns(episodes)
    est = stats.pooled_estimates(cols, pool, rng, n_resamples, level)
    secs = [float(ep.get("seconds", math.nan)) for ep in episodes]
    cells = {}
    for path, e in est.items():
        ok = [s for s, v in zip(secs, cols[path], strict=True) if not math.isnan(v)]
        cells[path] = _cell(e, cols[path], float(np.sum(ok)))
    nested = _nest(cells)
    s: dict[str, Any] = {"n_episodes": len(episodes), "seeds": [int(ep["seed"]) for ep in episodes],
                         "seconds": float(np.nansum(secs))}
    for key in ("servo_error_mdeg", "pointing_error_mdeg", "cost_per_step", "rate_command_deg_s",
                "controller_time_ms"):
        s[key] = nested[key]
    s["limit_hits"] = {k: int(sum(ep["limit_hits"][k] for ep in episodes)) for k in ("rate", "accel")}
    s["limit_hits"]["per_episode"] = nested["limit_hits"]
    s["fallbacks"] = int(sum(ep.get("fallbacks", 0) for ep in episodes))
    s["failures"] = int(sum(ep["failures"] for ep in episodes))
    s["terminated"] = int(sum(ep["terminated"] for ep in episodes))
    if "step" in nested:
        s["step"] = nested["step"]
    return s


def _ratio_dict(r: stats.Ratio) -> dict[str, Any]:
    return {"value": r.value, "ci95": [r.low, r.high], "significant": r.significant,
            "n_episodes": r.n_num}


def reference_ratios(episodes: Sequence[Mapping[str, Any]], reference: Sequence[Mapping[str, Any]],
                     rng: np.random.Generator, n_resamples: int = N_RESAMPLES,
                     level: float = LEVEL) -> dict[str, Any]:
    """Pooled 3σ of ``episodes`` over the reference's, per axis, on the seeds both ran
    (paired bootstrap).
    """
    ref = {int(ep["seed"]): ep for ep in reference}
    common = [ep for ep in episodes if int(ep["seed"]) in ref]
    num = {ax: [ep["servo_error_mdeg"][ax]["three_sigma"] for ep in common] for ax in AXES}
    den = {ax: [ref[int(ep["seed"])]["servo_error_mdeg"][ax]["three_sigma"] for ep in common]
           for ax in AXES}
    r = stats.paired_ratios(num, den, {ax: "rms" for ax in AXES}, rng, n_resamples, level)
    return {ax: _ratio_dict(r[ax]) for ax in AXES}


def yardstick_ratios(summary: Mapping[str, Any], ref: Mapping[str, Any]) -> dict[str, Any]:
    """Pooled 3σ per axis over the yardstick's analytic (exact) expected 3σ; the interval is
    the controller's, divided by the same number.
    """
    out = {}
    for i, ax in enumerate(AXES):
        c = summary["servo_error_mdeg"][ax]["three_sigma"]
        y = float(ref["three_sigma_mdeg"][i])
        r = stats.Ratio(c["value"] / y, c["ci95"][0] / y, c["ci95"][1] / y, c["n_episodes"], 1,
                        "the controller's interval over the analytic figure")
        out[ax] = _ratio_dict(r)
    return out


def yardstick_reference(scenario: Scenario, env: Any) -> dict[str, Any] | None:
    """The yardstick's expected performance for a scenario with one fixed wind, else None."""
    kw = scenario.env
    speed, direction = kw.get("wind_speed_kmh"), kw.get("wind_direction")
    if not isinstance(speed, (int, float)) or speed <= 0 or direction in (None, "random"):
        return None
    from dss14_env.baselines.yardstick import expected_performance
    return expected_performance(env, speed * KMH, direction)


def _chunks(seeds: Sequence[int], steps: int) -> list[list[int]]:
    size = max(1, MAX_ROW_STEPS // max(1, steps))
    return [list(seeds[i:i + size]) for i in range(0, len(seeds), size)]


@dataclass
class _ScenarioEnvs:
    """The environments of one scenario: the single one and vector ones by size."""

    kwargs: dict[str, Any]
    single: Any
    vectors: dict[int, Any]

    def vector(self, n: int) -> Any:
        if n not in self.vectors:
            self.vectors[n] = _make_vector_env(self.kwargs, n)
        return self.vectors[n]


def _controller_episodes(ctrl: Controller, envs: _ScenarioEnvs, seeds: Sequence[int], n_seq: int,
                         steps: int, warmup_s: float, record: bool, batch: bool,
                         progress: Callable[[list[dict[str, Any]]], None]
                         ) -> tuple[list[dict[str, Any]], bool]:
    """All episodes of one controller in one scenario, and whether it ran batched."""
    driver = batch_driver(ctrl) if batch else None
    eps: list[dict[str, Any]] = []
    if driver is not None:
        for chunk in _chunks(seeds, steps):
            new = run_rows(driver, envs.vector(len(chunk)), chunk, steps, warmup_s, record=record and not eps)
            eps += new
            progress(new)
    else:
        seq = _Sequential(ctrl)
        for seed in seeds[:n_seq]:
            new = run_rows(seq, envs.single, [seed], steps, warmup_s, record=record and not eps)
            eps += new
            progress(new)
    return eps, driver is not None


def _check_run(names: list[str], scens: list, seeds: list[int], sequential_seeds: int | None) -> int:
    if not names or not scens or not seeds:
        raise ValueError("run() needs at least one controller, one scenario and one seed")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be unique, got {seeds}")
    if len(set(names)) != len(names):
        raise ValueError(f"controller names must be unique, got {names}")
    n_seq = len(seeds) if sequential_seeds is None else int(sequential_seeds)
    if not 0 <= n_seq <= len(seeds):
        raise ValueError(f"sequential_seeds must be in 0..{len(seeds)}, got {sequential_seeds!r}")
    return n_seq


def _statistics_meta(n_resamples: int, bootstrap_seed: int) -> dict[str, Any]:
    return {"level": LEVEL, "n_resamples": n_resamples, "bootstrap_seed": bootstrap_seed,
            "interval": "percentile bootstrap over episodes (all metrics of a cell resampled together)",
            "ratios": "vs_reference: paired bootstrap over the common seeds; vs_yardstick: the "
                      "controller's interval over the analytic figure",
            "pooling": dict(POOLING)}


def _run_scenario(ctrls: list[tuple[str, Callable[[Any], Controller]]], sname: str, sc: Scenario,
                  seeds: list[int], n_seq: int, kw: dict[str, Any], n_steps: int, record: bool, batch: bool,
                  progress: Callable[[str, int], None] | None, reference: str | None, bootstrap_seed: int,
                  n_resamples: int) -> tuple[list[dict[str, Any]], dict[str, Any], Any, dict[str, Any]]:
    """Every controller on one scenario: its episodes, summary cells, yardstick reference and,
    per controller, whether it ran batched and its wall time (s, building it included).
    """
    envs = _ScenarioEnvs(kw, _make_env(kw), {})
    ref = yardstick_reference(sc, envs.single)
    by_ctrl: dict[str, list[dict[str, Any]]] = {}
    cells: dict[str, Any] = {}
    flags: dict[str, Any] = {}
    for cname, factory in ctrls:
        t0 = time.perf_counter()
        if n_seq == 0 and known_unbatchable(factory):
            flags[cname] = (False, 0.0)
            continue
        def tick(eps: list[dict[str, Any]], c: str = cname) -> None:
            if progress is not None:
                progress(_progress_line(c, sname, eps), len(eps))
        eps, batched = _controller_episodes(factory(envs.single), envs, seeds, n_seq, n_steps,
                                            sc.warmup_s, record, batch, tick)
        flags[cname] = (batched, time.perf_counter() - t0)
        for ep in eps:
            ep.update({"controller": cname, "scenario": sname})
        if eps:
            by_ctrl[cname] = eps
            cells[cname] = summarise(eps, cell_rng(cname, sname, seed=bootstrap_seed), n_resamples)
            if ref is not None:
                cells[cname]["vs_yardstick"] = yardstick_ratios(cells[cname], ref)
    if reference in by_ctrl:
        for cname, eps in by_ctrl.items():
            cells[cname]["vs_reference"] = reference_ratios(
                eps, by_ctrl[reference], cell_rng(cname, reference, sname, seed=bootstrap_seed), n_resamples)
    return [ep for eps in by_ctrl.values() for ep in eps], cells, ref, flags


def run(controllers: Iterable[Any], scenarios: Iterable[Any], seeds: Iterable[int],
        env_kwargs: Mapping[str, Any] | None = None, steps: int | None = None,
        progress: Callable[[str, int], None] | None = None, record: bool = False,
        sequential_seeds: int | None = None, batch: bool = True, reference: str | None = REFERENCE,
        bootstrap_seed: int = 0, n_resamples: int = N_RESAMPLES) -> dict[str, Any]:
    """Score controllers on scenarios over seeds.

    :param controllers: names of :data:`CONTROLLERS`, :class:`Controller` instances or
        ``(name, factory(env))`` pairs
    :param scenarios: names of :data:`SCENARIOS` or ``(name, Scenario)`` pairs
    :param seeds: episode seeds (the same for every controller)
    :param env_kwargs: environment keys applied on top of every scenario's (e.g.
        ``{"randomize_params": True}``)
    :param steps: episode length overriding the scenarios' (control periods)
    :param progress: called with a line and the number of episodes it finished, per batch or
        episode
    :param record: keep the first seed's time histories under ``episodes[i]["trace"]``
        (:func:`run_rows`; numpy arrays, left out of the JSON conversion -- drop them before
        ``json.dump``); default False
    :param sequential_seeds: controllers without the batch interface run only the first this
        many seeds (default: all)
    :param batch: drive batchable controllers through the vector environment (default); False
        runs every controller one episode at a time
    :param reference: the controller of ``vs_reference`` (default ``pi_kp1``; skipped when it
        does not run)
    :param bootstrap_seed: seed of the bootstrap generators
    :param n_resamples: bootstrap resamples
    :return: ``{"meta", "episodes", "summary", "yardstick"}``, JSON-serialisable (without
        traces): ``summary[controller][scenario]`` (:func:`summarise`, plus ``vs_reference`` and
        ``vs_yardstick`` where defined)
    """
    ctrls = [_resolve_controller(c) for c in controllers]
    scens = [_resolve_scenario(s) for s in scenarios]
    seeds = [int(s) for s in seeds]
    names = [n for n, _ in ctrls]
    n_seq = _check_run(names, scens, seeds, sequential_seeds)
    env_kwargs = dict(env_kwargs or {})
    episodes: list[dict[str, Any]] = []
    summary: dict[str, dict[str, Any]] = {n: {} for n in names}
    yard: dict[str, Any] = {}
    batched: dict[str, bool] = {}
    wall: dict[str, dict[str, float]] = {n: {} for n in names}
    t_start = time.perf_counter()
    for sname, sc in scens:
        eps, cells, ref, flags = _run_scenario(ctrls, sname, sc, seeds, n_seq, {**sc.env, **env_kwargs},
                                               int(steps or sc.steps), record, batch, progress, reference,
                                               bootstrap_seed, n_resamples)
        episodes += eps
        for cname, (b, t) in flags.items():
            batched[cname] = b
            wall[cname][sname] = t
        for cname, cell in cells.items():
            summary[cname][sname] = cell
        if ref is not None:
            yard[sname] = ref
    meta = {"controllers": names, "scenarios": [n for n, _ in scens], "seeds": seeds,
            "sequential_seeds": seeds[:n_seq], "batched": batched,
            "reference": reference if reference in names else None,
            "env_kwargs": env_kwargs, "steps": {n: int(steps or sc.steps) for n, sc in scens},
            "warmup_s": {n: sc.warmup_s for n, sc in scens},
            "statistics": _statistics_meta(n_resamples, bootstrap_seed),
            "wall_time_s": time.perf_counter() - t_start, "controller_wall_time_s": wall}
    traces = [ep.pop("trace", None) for ep in episodes]
    out = jsonable({"meta": meta, "episodes": episodes, "summary": summary, "yardstick": yard})
    for ep, tr in zip(out["episodes"], traces, strict=True):
        if tr is not None:
            ep["trace"] = tr
    return out


def _progress_line(cname: str, sname: str, eps: Sequence[Mapping[str, Any]]) -> str:
    se = [ep["servo_error_mdeg"] for ep in eps]
    az = float(np.mean([s["az"]["three_sigma"] for s in se]))
    el = float(np.mean([s["el"]["three_sigma"] for s in se]))
    seeds = f"seed {eps[0]['seed']}" if len(eps) == 1 else f"{len(eps)} seeds"
    return f"{cname:>10s} {sname:>10s} {seeds}: 3-sigma az {az:.3f} el {el:.3f} mdeg"


def ratio(summary: Mapping[str, Any], num: str, den: str, scenario: str, axis: str,
          stat: str = "three_sigma") -> float:
    """``summary[num][scenario]`` over ``summary[den][scenario]`` for the pooled value of a
    servo-error statistic on one axis (e.g. LQG over PI; ``vs_reference`` has it with its
    interval).
    """
    a = summary[num][scenario]["servo_error_mdeg"][axis][stat]["value"]
    b = summary[den][scenario]["servo_error_mdeg"][axis][stat]["value"]
    return float(a / b)


def jsonable(x: Any) -> Any:
    """``x`` with numpy scalars and arrays turned into Python numbers and lists."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [jsonable(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x
