"""The one runner that scores every controller the same way: controller x scenario x seeds.

>>> res = run(["pi_kp1"], ["hold_side"], seeds=[0], steps=300)
>>> s = res["summary"]["pi_kp1"]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]["median"]
>>> 0.5 < s < 5.0     # mdeg: the report's PI in 50 km/h side wind (Table 4: 2.1)
True

Every episode is an environment ``DSS14Env(**scenario_env, **env_kwargs)`` reset with the seed,
so every controller sees the same start, wind direction, trajectory and gust realisation for
the same seed (the environment draws nothing that depends on the actions).  Controllers are
built once per scenario from a factory that gets the environment (they read its interface,
never its plant) and reset for each episode.  A controller with a ``set_scenario(speed,
direction)`` method (the yardstick, an oracle of the scenario's wind) is told the episode's
wind from the reset info.

Metrics per episode (:func:`episode_metrics`), all JSON-ready, angles in mdeg:

* ``servo_error_mdeg`` per axis: ``three_sigma`` (3 x standard deviation about the mean, the
  report's 3-sigma), ``rms`` (includes the mean), ``max`` (largest magnitude), ``mean``;
  evaluated after the scenario's warm-up (hold, track: 5 s) -- the true errors of the env info;
* ``pointing_error_mdeg``: the same for the dish's true el / xel pointing error;
* ``cost_per_step``: mean of the negated reward over the window;
* ``step`` (scenarios with a command step): per axis ``overshoot_pct`` and
  ``settling_time_s`` (2 % band, from the step time);
* ``rate_command_deg_s``: per axis ``rms`` and ``peak`` of the applied command, and the largest
  applied change per second (``peak_accel_deg_s2``);
* ``limit_hits``: steps where the env's limiter clipped the rate or its change;
* ``controller_time_ms``: ``median``, ``p95``, ``max`` of the wall time of ``act()``;
* ``fallbacks`` / ``failures``: MPC fallbacks to the LQG action (``info["n_fallbacks"]``),
  exceptions raised by a controller (the episode then ends, counted as failed);
* ``terminated`` and the number of steps.

:func:`run` aggregates them over seeds (median, mean, min, max) per controller and scenario
and, for windy scenarios with a fixed wind, divides each controller's 3-sigma by the
yardstick's expected value (:func:`dss14_env.baselines.yardstick.expected_performance`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from dss14_env.baselines.base import Controller
from dss14_env.envs.presets import PRESETS

DEG = math.pi / 180.0


@dataclass(frozen=True)
class Scenario:
    """One benchmark scenario: environment keys, episode length and metric window.

    :param env: keyword arguments of :class:`dss14_env.envs.env.DSS14Env`
    :param steps: control periods per episode
    :param warmup_s: seconds at the start left out of the error statistics
    """

    env: Mapping[str, Any]
    steps: int
    warmup_s: float = 0.0
    description: str = ""


#: episode lengths of the benchmark scenarios where they differ from the preset's registered
#: ``max_episode_steps`` (control periods)
_SCENARIO_STEPS = {"step": 1000, "slew": 2500}
#: the benchmark scenarios: the environment presets (:data:`dss14_env.envs.presets.PRESETS`)
#: with one fixed wind direction or none
SCENARIOS: dict[str, Scenario] = {
    name: Scenario(dict(PRESETS[name].kwargs), _SCENARIO_STEPS.get(name, PRESETS[name].max_episode_steps),
                   PRESETS[name].warmup_s, PRESETS[name].description)
    for name in ("hold_front", "hold_side", "step", "track", "slew")}


def _pi(gains: str) -> Callable[[Any], Controller]:
    def make(env: Any) -> Controller:
        from dss14_env.baselines.pi import PIController
        return PIController(env, gains)
    return make


def _lazy(module: str, cls: str) -> Callable[[Any], Controller]:
    def make(env: Any) -> Controller:
        import importlib
        return getattr(importlib.import_module(module), cls)(env)
    return make


#: controller factories by name (each gets the environment)
CONTROLLERS: dict[str, Callable[[Any], Controller]] = {
    "pi_kp1": _pi("kp1"),
    "pi_kp0.7": _pi("kp0.7"),
    "lqg": _lazy("dss14_env.baselines.lqg", "LQGController"),
    "mpc": _lazy("dss14_env.baselines.mpc", "MPCController"),
    "yardstick": _lazy("dss14_env.baselines.yardstick", "YardstickController"),
}


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
        ``cost`` (n,), ``hits`` (n, 2) rate/accel limiter flags, ``t_ctrl`` (n,) act() times (s)
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
        "servo_error_mdeg": {ax: _stats(e[w, i]) for i, ax in enumerate(("az", "el"))},
        "pointing_error_mdeg": {ax: _stats(p[w, i]) for i, ax in enumerate(("el", "xel"))},
        "cost_per_step": float(np.mean(rec["cost"][w])) if np.any(w) else math.nan,
    }
    r = rec["r"] if n else np.zeros((1, 2))
    dr = np.abs(np.diff(r, axis=0)) / dt if n > 1 else np.zeros((0, 2))
    out["rate_command_deg_s"] = {ax: {"rms": float(np.sqrt(np.mean(r[:, i] ** 2))),
                                      "peak": float(np.max(np.abs(r[:, i]))),
                                      "peak_accel_deg_s2": float(dr[:, i].max()) if dr.size else 0.0}
                                 for i, ax in enumerate(("az", "el"))}
    out["limits"] = dict(limits)
    out["limit_hits"] = {"rate": int(rec["hits"][:, 0].sum()), "accel": int(rec["hits"][:, 1].sum())}
    tc = np.asarray(rec["t_ctrl"]) * 1e3 if len(rec["t_ctrl"]) else np.zeros(1)
    out["controller_time_ms"] = {"median": float(np.median(tc)), "p95": float(np.percentile(tc, 95)),
                                 "max": float(tc.max())}
    if step is not None:
        theta = rec["c"] * 1e3 - e  # mdeg
        out["step"] = {ax: step_response(t, theta[:, i], step["size_deg"][i] * 1e3, step["time_s"])
                       for i, ax in enumerate(("az", "el")) if step["size_deg"][i] != 0}
    return out


# ------------------------------------------------------------------------- running
def _make_env(env_kwargs: Mapping[str, Any]) -> Any:
    from dss14_env.envs.env import DSS14Env
    return DSS14Env(**dict(env_kwargs))


def _resolve_controller(c: Any) -> tuple[str, Callable[[Any], Controller]]:
    if isinstance(c, str):
        if c not in CONTROLLERS:
            raise ValueError(f"unknown controller {c!r}; known: {sorted(CONTROLLERS)}")
        return c, CONTROLLERS[c]
    if isinstance(c, Controller):
        return c.name, (lambda env, _c=c: _c)
    if isinstance(c, tuple) and len(c) == 2 and isinstance(c[0], str) and callable(c[1]):
        return c[0], c[1]
    raise TypeError(f"a controller must be a name of {sorted(CONTROLLERS)}, a Controller or a "
                    f"(name, factory(env)) pair, got {c!r}")


def _resolve_scenario(s: Any) -> tuple[str, Scenario]:
    if isinstance(s, str):
        if s not in SCENARIOS:
            raise ValueError(f"unknown scenario {s!r}; known: {sorted(SCENARIOS)}")
        return s, SCENARIOS[s]
    if isinstance(s, tuple) and len(s) == 2 and isinstance(s[1], Scenario):
        return s
    raise TypeError(f"a scenario must be a name of {sorted(SCENARIOS)} or a (name, Scenario) "
                    f"pair, got {s!r}")


def run_episode(ctrl: Controller, env: Any, seed: int, steps: int, warmup_s: float = 0.0,
                record: bool = False) -> dict[str, Any]:
    """One episode of one controller; returns :func:`episode_metrics` plus ``seed``,
    ``terminated``, ``failures``, ``fallbacks`` and the episode's wind.

    :param record: also return the time histories under ``"trace"`` (numpy arrays, one row per
        step taken: ``t`` (s, end of the step), ``servo_error_mdeg`` (n, 2) true az/el errors,
        ``command_deg`` (n, 2) and ``encoder_deg`` (n, 2) commanded position and encoder reading
        relative to the start, ``rate_command_deg_s`` (n, 2) applied rate commands); off by
        default, the output is then unchanged
    """
    cfg = env.unwrapped.config
    obs, info = env.reset(seed=seed)
    if hasattr(ctrl, "set_scenario"):
        ctrl.set_scenario(info["wind_speed_mps"], info["wind_direction_rad"])
    ctrl.reset(seed)
    e = np.zeros((steps, 2))
    p = np.zeros((steps, 2))
    c = np.zeros((steps, 2))
    r = np.zeros((steps, 2))
    cost = np.zeros(steps)
    hits = np.zeros((steps, 2), bool)
    tc = np.zeros(steps)
    enc = np.zeros((steps, 2)) if record else None
    terminated, failure, k = False, None, 0
    for k in range(steps):
        t0 = time.perf_counter()
        try:
            a = ctrl.act(obs)
        except Exception as exc:  # noqa: BLE001 - a controller failure is a result, not a crash
            failure = f"{type(exc).__name__}: {exc}"
            break
        tc[k] = time.perf_counter() - t0
        obs, rew, terminated, _, info = env.step(a)
        e[k] = info["servo_error_az_mdeg"], info["servo_error_el_mdeg"]
        p[k] = info["pointing_error_el_mdeg"], info["pointing_error_xel_mdeg"]
        c[k] = obs[4], obs[5]
        r[k] = info["rate_command_az_deg_s"], info["rate_command_el_deg_s"]
        cost[k] = -rew
        hits[k] = info["rate_limited"], info["accel_limited"]
        if enc is not None:
            enc[k] = obs[8], obs[9]
        if terminated:
            k += 1
            break
    else:
        k = steps
    n = k
    rec = {"e": e[:n], "p": p[:n], "c": c[:n], "r": r[:n], "cost": cost[:n], "hits": hits[:n],
           "t_ctrl": tc[:max(n, 1)]}
    step = None
    if cfg.scenario == "step":
        mask = {"az": (1.0, 0.0), "el": (0.0, 1.0), "both": (1.0, 1.0)}[cfg.step_axes]
        step = {"size_deg": [cfg.step_deg * m for m in mask], "time_s": cfg.step_time_s}
    m = episode_metrics(rec, cfg.dt, warmup_s, step,
                        {"rate_deg_s": cfg.rate_limit_deg_s, "accel_deg_s2": cfg.accel_limit_deg_s2})
    m.update({"seed": int(seed), "terminated": bool(terminated), "failures": int(failure is not None),
              "failure": failure, "fallbacks": int(ctrl.info.get("n_fallbacks", 0)),
              "wind_speed_mps": float(info.get("wind_speed_mps", 0.0)),
              "wind_direction_rad": float(info.get("wind_direction_rad", 0.0))})
    if enc is not None:
        m["trace"] = {"t": (np.arange(n) + 1) * cfg.dt, "servo_error_mdeg": e[:n].copy(),
                      "command_deg": c[:n].copy(), "encoder_deg": enc[:n].copy(),
                      "rate_command_deg_s": r[:n].copy()}
    return m


def _aggregate(values: Sequence[float]) -> dict[str, float]:
    v = np.asarray([x for x in values if x is not None], float)
    if v.size == 0:
        return {"median": math.nan, "mean": math.nan, "min": math.nan, "max": math.nan}
    return {"median": float(np.median(v)), "mean": float(np.mean(v)), "min": float(np.min(v)),
            "max": float(np.max(v))}


def summarise(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Aggregate per-episode metrics of one controller and scenario over seeds."""
    s: dict[str, Any] = {"n_episodes": len(episodes)}
    for key, axes in (("servo_error_mdeg", ("az", "el")), ("pointing_error_mdeg", ("el", "xel"))):
        s[key] = {ax: {stat: _aggregate([ep[key][ax][stat] for ep in episodes])
                       for stat in ("three_sigma", "rms", "max")} for ax in axes}
    s["cost_per_step"] = _aggregate([ep["cost_per_step"] for ep in episodes])
    s["rate_command_deg_s"] = {ax: {stat: _aggregate([ep["rate_command_deg_s"][ax][stat] for ep in episodes])
                                    for stat in ("rms", "peak", "peak_accel_deg_s2")} for ax in ("az", "el")}
    s["limit_hits"] = {k: int(sum(ep["limit_hits"][k] for ep in episodes)) for k in ("rate", "accel")}
    s["controller_time_ms"] = {k: _aggregate([ep["controller_time_ms"][k] for ep in episodes])
                               for k in ("median", "p95", "max")}
    s["fallbacks"] = int(sum(ep["fallbacks"] for ep in episodes))
    s["failures"] = int(sum(ep["failures"] for ep in episodes))
    s["terminated"] = int(sum(ep["terminated"] for ep in episodes))
    if any("step" in ep for ep in episodes):
        axes = sorted({ax for ep in episodes for ax in ep.get("step", {})})
        s["step"] = {ax: {k: _aggregate([ep["step"][ax][k] for ep in episodes if ax in ep.get("step", {})])
                          for k in ("overshoot_pct", "settling_time_s")} for ax in axes}
    return s


def yardstick_reference(scenario: Scenario, env: Any) -> dict[str, Any] | None:
    """The yardstick's expected performance for a scenario with one fixed wind, else None."""
    kw = scenario.env
    speed, direction = kw.get("wind_speed_kmh"), kw.get("wind_direction")
    if not isinstance(speed, (int, float)) or speed <= 0 or direction in (None, "random"):
        return None
    from dss14_env.baselines.interface import ControlInterface as EnvSpec
    from dss14_env.baselines.yardstick import expected_performance
    return expected_performance(EnvSpec.from_env(env), speed / 3.6, direction)


def run(controllers: Iterable[Any], scenarios: Iterable[Any], seeds: Iterable[int],
        env_kwargs: Mapping[str, Any] | None = None, steps: int | None = None,
        progress: Callable[[str], None] | None = None, record: bool = False) -> dict[str, Any]:
    """Score controllers on scenarios over seeds.

    :param controllers: names of :data:`CONTROLLERS`, :class:`Controller` instances or
        ``(name, factory(env))`` pairs
    :param scenarios: names of :data:`SCENARIOS` or ``(name, Scenario)`` pairs
    :param seeds: episode seeds (the same for every controller)
    :param env_kwargs: environment keys applied on top of every scenario's (e.g.
        ``{"randomize_params": True}``)
    :param steps: episode length overriding the scenarios' (control periods)
    :param progress: called with a line per finished episode
    :param record: keep each episode's time histories under ``episodes[i]["trace"]``
        (:func:`run_episode`; numpy arrays, left out of the JSON conversion -- drop them before
        ``json.dump``); default False: no traces
    :return: ``{"meta", "episodes", "summary", "yardstick"}``, JSON-serialisable:
        ``summary[controller][scenario]`` (:func:`summarise`, plus ``vs_yardstick`` -- the
        median 3-sigma per axis divided by the yardstick's expected one -- where the scenario
        has a fixed wind)
    """
    ctrls = [_resolve_controller(c) for c in controllers]
    scens = [_resolve_scenario(s) for s in scenarios]
    seeds = [int(s) for s in seeds]
    if not ctrls or not scens or not seeds:
        raise ValueError("run() needs at least one controller, one scenario and one seed")
    names = [n for n, _ in ctrls]
    if len(set(names)) != len(names):
        raise ValueError(f"controller names must be unique, got {names}")
    env_kwargs = dict(env_kwargs or {})
    episodes: list[dict[str, Any]] = []
    summary: dict[str, dict[str, Any]] = {n: {} for n in names}
    yard: dict[str, Any] = {}
    t_start = time.perf_counter()
    for sname, sc in scens:
        env = _make_env({**sc.env, **env_kwargs})
        n_steps = int(steps or sc.steps)
        ref = yardstick_reference(sc, env)
        if ref is not None:
            yard[sname] = ref
        for cname, factory in ctrls:
            ctrl = factory(env)
            eps = []
            for seed in seeds:
                m = run_episode(ctrl, env, seed, n_steps, sc.warmup_s, record=record)
                m.update({"controller": cname, "scenario": sname})
                eps.append(m)
                if progress is not None:
                    se = m["servo_error_mdeg"]
                    progress(f"{cname:>10s} {sname:>10s} seed {seed}: 3-sigma az "
                             f"{se['az']['three_sigma']:.3f} el {se['el']['three_sigma']:.3f} mdeg")
            episodes.extend(eps)
            s = summarise(eps)
            if ref is not None:
                s["vs_yardstick"] = {
                    ax: s["servo_error_mdeg"][ax]["three_sigma"]["median"] / ref["three_sigma_mdeg"][i]
                    for i, ax in enumerate(("az", "el"))}
            summary[cname][sname] = s
    meta = {"controllers": names, "scenarios": [n for n, _ in scens], "seeds": seeds,
            "env_kwargs": env_kwargs, "steps": {n: int(steps or sc.steps) for n, sc in scens},
            "warmup_s": {n: sc.warmup_s for n, sc in scens}, "wall_time_s": time.perf_counter() - t_start}
    traces = [ep.pop("trace", None) for ep in episodes]
    out = _jsonable({"meta": meta, "episodes": episodes, "summary": summary, "yardstick": yard})
    if record:
        for ep, tr in zip(out["episodes"], traces):
            ep["trace"] = tr
    return out


def ratio(summary: Mapping[str, Any], num: str, den: str, scenario: str, axis: str,
          stat: str = "three_sigma") -> float:
    """``summary[num][scenario]`` over ``summary[den][scenario]`` for the median of a servo-error
    statistic on one axis (e.g. LQG over PI)."""
    a = summary[num][scenario]["servo_error_mdeg"][axis][stat]["median"]
    b = summary[den][scenario]["servo_error_mdeg"][axis][stat]["median"]
    return float(a / b)


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [_jsonable(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x
