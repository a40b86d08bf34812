"""Evaluation of trained policies on seeds never seen in training.

Seed protocol of the DSS14 runs (checked when training starts):

* **test** seeds 0-999: the benchmark's; the final evaluation uses :data:`TEST_SEEDS` (0-9).
  They are **sealed**: every evaluation here (:func:`run_task`) refuses them
  (:class:`SealedSeedError`, :func:`check_unsealed`) unless the caller is the final scoring and
  says so with the token :data:`FINAL_SCORING` -- a campaign's test scores of its seeds'
  selected policies and the references beside them.  Validation, selection and recipe research
  (a sweep ranks its points on :data:`RESEARCH_SEEDS`) cannot read them;
* **validation** seeds 1000-9999: the periodic evaluation during training (``eval_seeds``),
  which picks ``eval/best``, and the held-out seeds of recipe research (:data:`RESEARCH_SEEDS`);
* **training** seeds 10 000 and up: sub-environment ``i`` of a run with ``seed`` s starts
  from ``s + i``.

The tasks of a DSS14 run are by default the benchmark's hold scenarios (:data:`DSS14_TASKS`):
50 km/h front wind scored on elevation, side wind on azimuth (the axis the wind loads), 3σ of
the servo error after the 5-s warm-up, in mdeg, the report's Table 4 figure; beside it the 3σ
of the dish's true pointing error on the axis the wind swings (front: elevation, side:
cross-elevation; the environment's ``pointing_error_*_mdeg``).  Every other bench scenario is
a task too (:data:`SCENARIO_TASKS`, :func:`dss14_tasks` with ``scenarios``: the track, the
0.1° step, the 5° slew, the axis-encoder holds), in the default bench run's episode length.
For any other environment the one task is the configured environment and the score its
return.

A DSS14 task's episodes run through the benchmark's one episode loop
(:func:`dss14_env.baselines.rollout.run_rows`): the seeds as rows of the vector environment
for a batchable controller (:meth:`dss14_env.agents.policy.PolicyController.act_batch`), as the
bench's runner runs them, and every episode's figures are the bench's
(:func:`~dss14_env.baselines.rollout.episode_metrics`, :data:`FIGURES`): a policy's figure here
is its bench figure on the same seed and length.  Any other environment's episodes run in
lockstep, one environment per seed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, final

import gymnasium as gym
import numpy as np

from dss14_env.core.smoothness import high_frequency_share
from dss14_env.envs.config import load_env_config
from dss14_env.envs.presets import PRESETS

#: the seed ranges of the protocol (see the module doc)
TEST_SEED_RANGE = (0, 1000)
VALIDATION_SEED_RANGE = (1000, 10_000)
TRAINING_SEED_START = 10_000
#: the final evaluation: test seeds and episode length (60 s at 50 Hz)
TEST_SEEDS = tuple(range(10))
TEST_STEPS = 3000
#: the seeds recipe research (a sweep's ranking) scores its points on: validation seeds that the
#: shipped recipes' periodic validation (1000-1005) does not use, never the sealed test seeds
RESEARCH_SEEDS = tuple(range(2000, 2010))
#: the pointing-error axis swung with each loaded drive axis: elevation, cross-elevation
POINTING_AXIS_OF = {"el": "el", "az": "xel"}


class SealedSeedError(ValueError):
    """An evaluation other than the final scoring asked for a sealed test seed."""


@final
class FinalScoring:
    """The type of :data:`FINAL_SCORING`, the one token that opens the sealed test seeds."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "FINAL_SCORING"


#: the token the final scoring passes (``access=FINAL_SCORING``) to read the sealed test seeds
FINAL_SCORING = FinalScoring()


def check_unsealed(seeds: Sequence[int], access: FinalScoring | None = None,
                   where: str = "evaluation") -> None:
    """Refuse the sealed test seeds (:data:`TEST_SEED_RANGE`) to anything but the final scoring:
    the one guard of every evaluation path (:func:`run_task`).

    >>> check_unsealed([1000, 2000])
    >>> check_unsealed([3], FINAL_SCORING)
    >>> try:
    ...     check_unsealed([1000, 3], where="validation")
    ... except SealedSeedError as exc:
    ...     print(str(exc)[:48])
    validation: seed 3 is a sealed test seed (0-999)

    :param seeds: the seeds asked for
    :param access: :data:`FINAL_SCORING` for the final scoring; None for everything else
    :param where: who asks (named in the error)
    :raises SealedSeedError: a seed in the sealed range without the token
    """
    if access is FINAL_SCORING:
        return
    lo, hi = TEST_SEED_RANGE
    sealed = [int(s) for s in seeds if lo <= int(s) < hi]
    if sealed:
        raise SealedSeedError(
            f"{where}: seed {sealed[0]} is a sealed test seed ({lo}-{hi - 1}): only the final "
            f"scoring reads them (access=FINAL_SCORING); validate, select and research on the "
            f"validation seeds {VALIDATION_SEED_RANGE[0]}-{VALIDATION_SEED_RANGE[1] - 1}")


@dataclass(frozen=True)
class EvalTask:
    """One evaluation task.

    :param name: label (``hold_front``)
    :param env_id: the environment the episodes run in (plain observations for DSS14)
    :param env_kwargs: its ``gymnasium.make`` keyword arguments
    :param axis: ``"az"`` / ``"el"``: score the 3σ servo error of that axis; None: return only
    :param warmup_steps: steps left out of the 3σ
    :param pointing_axis: ``"el"`` / ``"xel"``: score the 3σ pointing error of that axis too;
        None: not scored
    :param preset: the DSS14 preset (:data:`~dss14_env.envs.presets.PRESETS`) the task runs:
        its episodes run through the shared episode loop and get the bench's figures; None:
        any other environment (its own loop, returns only)
    :param steps: episode length without ``steps`` in :func:`run_task` (None: the
        environment's)
    """

    name: str
    env_id: str
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    axis: str | None = None
    warmup_steps: int = 0
    pointing_axis: str | None = None
    preset: str | None = None
    steps: int | None = None


#: the benchmark scenarios as evaluation tasks: name -> (preset, environment keys on top of the
#: preset's, episode length in steps of the default ``dt`` or None for the preset's): every
#: preset under its own name, and the variants and default episode lengths of the bench's run
#: (the catalog's rows and their default budgets, :data:`dss14_env.bench.catalog.SCENARIO_ROWS`:
#: 40-s track, 20-s step, 50-s slew; tests/test_agents_evaluation.py holds the two equal)
SCENARIO_TASKS: Mapping[str, tuple[str, Mapping[str, Any], int | None]] = MappingProxyType({
    **{name: (name, {}, None) for name in PRESETS},
    "step": ("step", {}, 1000),
    "track": ("track", {}, 2000),
    "slew": ("slew", {}, 2500),
    "hold_front_axis": ("hold_front", {"encoders": "axis"}, None),
    "hold_side_axis": ("hold_side", {"encoders": "axis"}, None),
})
#: the scenarios of a DSS14 run's validation and test tasks unless configured otherwise
DEFAULT_SCENARIOS = ("hold_front", "hold_side")
#: the per-episode figures :func:`run_task` returns for a DSS14 task, from the bench's episode
#: records (:func:`dss14_env.baselines.rollout.episode_metrics`): key -> path in the record
#: (NaN where the record has none, e.g. no step)
FIGURES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "servo_three_sigma_mdeg_az": ("servo_error_mdeg", "az", "three_sigma"),
    "servo_three_sigma_mdeg_el": ("servo_error_mdeg", "el", "three_sigma"),
    "pointing_three_sigma_mdeg_el": ("pointing_error_mdeg", "el", "three_sigma"),
    "pointing_three_sigma_mdeg_xel": ("pointing_error_mdeg", "xel", "three_sigma"),
    "overshoot_pct_az": ("step", "az", "overshoot_pct"),
    "overshoot_pct_el": ("step", "el", "overshoot_pct"),
    "settling_time_s_az": ("step", "az", "settling_time_s"),
    "settling_time_s_el": ("step", "el", "settling_time_s"),
    "pointing_settled_rms_mdeg_el": ("step", "pointing", "el", "settled_rms_mdeg"),
    "pointing_settled_rms_mdeg_xel": ("step", "pointing", "xel", "settled_rms_mdeg"),
    "rate_limit_hits": ("limit_hits", "rate"),
    "accel_limit_hits": ("limit_hits", "accel"),
})
def dss14_tasks(env_kwargs: Mapping[str, Any] | None = None,
                scenarios: Sequence[str] = DEFAULT_SCENARIOS) -> list[EvalTask]:
    """Benchmark scenarios (:data:`SCENARIO_TASKS`) as evaluation tasks, with ``env_kwargs``
    laid over; the warm-up in steps of the environment's ``dt``.  A scenario with one loaded
    axis (the presets' ``loaded_axes``: the holds) is scored on it, its pointing error on the
    axis the wind swings (:data:`POINTING_AXIS_OF`); the others (track, step, slew) have no
    ``axis`` (their figures are in :func:`run_task`'s per-axis entries).

    :param env_kwargs: environment keys on top of every scenario's
    :param scenarios: names of :data:`SCENARIO_TASKS`, default the two holds
    :raises ValueError: an unknown scenario, naming the known ones
    """
    unknown = [s for s in scenarios if s not in SCENARIO_TASKS]
    if unknown or not scenarios or len(set(scenarios)) != len(scenarios):
        raise ValueError(f"evaluation scenarios must be distinct names of {list(SCENARIO_TASKS)}, "
                         f"got {list(scenarios)}")
    kw = dict(env_kwargs or {})
    dt = float(kw["dt"]) if "dt" in kw else load_env_config().dt
    out = []
    for name in scenarios:
        preset, extra, steps = SCENARIO_TASKS[name]
        p = PRESETS[preset]
        axis = p.loaded_axes[0] if len(p.loaded_axes) == 1 else None
        out.append(EvalTask(name, p.env_id, {**extra, **kw}, axis, int(round(p.warmup_s / dt)),
                            None if axis is None else POINTING_AXIS_OF[axis], preset, steps))
    return out


#: the DSS14 evaluation tasks: hold in 50 km/h front wind (elevation), side wind (azimuth)
DSS14_TASKS = tuple(dss14_tasks())


def run_task(ctrl: Any, task: EvalTask, seeds: Sequence[int], steps: int | None = None,
             n_episodes: int = 1, access: FinalScoring | None = None) -> dict[str, Any]:
    """Run the controller's deterministic policy on one task.

    On a DSS14 task sealed test seeds are refused before any work (:func:`check_unsealed`)
    unless ``access`` is :data:`FINAL_SCORING`.

    A DSS14 task (``task.preset``) runs through the benchmark's episode loop
    (:func:`dss14_env.baselines.rollout.run_rows`: all seeds at once as rows of the vector
    environment for a batchable controller, as the bench runs it, or one by one) and takes its
    figures from the same :func:`~dss14_env.baselines.rollout.episode_metrics`, so an episode's
    figures equal the bench's for the same seed and length.  Any other task steps one
    environment per seed in lockstep through ``act_batch``.  For every seed the first episode
    starts with ``reset(seed=seed)``, the next ``n_episodes - 1`` continue the environment's
    generator.

    :param ctrl: a controller (``reset_batch``, ``act_batch``; for a DSS14 task any controller
        of the bench's interface)
    :param task: the task
    :param seeds: one environment per seed
    :param steps: episode length (control periods), default None: ``task.steps``, else the
        environment's (``max_episode_steps``)
    :param n_episodes: episodes per seed
    :param access: :data:`FINAL_SCORING` for the final scoring, else None
    :raises SealedSeedError: a sealed test seed without ``access``
    :return: arrays of ``n_episodes * len(seeds)`` (episode-major): ``returns``, ``lengths``,
        ``command_hf_share`` (:func:`~dss14_env.core.smoothness.high_frequency_share` of both
        axes pooled, after the warm-up; NaN for other tasks),
        ``three_sigma_mdeg`` (the servo error of ``task.axis``; NaN without an axis),
        ``pointing_three_sigma_mdeg`` (of ``task.pointing_axis``; NaN without one),
        ``terminated`` and, for a DSS14 task, every :data:`FIGURES` key (NaN for the others);
        a 3σ of fewer than two scored steps is NaN; ``episodes``: the bench's record of each
        episode (:func:`~dss14_env.baselines.rollout.run_rows`; empty for other tasks)
    """
    if task.preset is not None:  # the seed protocol is the DSS14 runs' (module doc)
        check_unsealed(seeds, access, f"run_task {task.name}")
    if n_episodes < 1 or not len(seeds):
        raise ValueError(f"run_task: need at least one seed and n_episodes >= 1, got "
                         f"{len(seeds)} seeds and n_episodes={n_episodes}")
    if task.preset is not None:
        return _run_bench_task(ctrl, task, seeds, steps, n_episodes)
    return _run_gym_task(ctrl, task, seeds, steps, n_episodes)


class _Returns:
    """An environment that sums each row's rewards until the row's episode ends and keeps the
    applied rate commands (what :func:`~dss14_env.baselines.rollout.run_rows` does not record).
    """

    def hf_shares(self, episodes: Sequence[Mapping[str, Any]], warmup_steps: int) -> list[float]:
        """Each row's share of the command change above 5 Hz, both axes pooled
        (:func:`~dss14_env.core.smoothness.high_frequency_share`), over its episode after the warm-up.
        """
        r = np.stack(self.rates) if self.rates else np.zeros((0, len(episodes), 2))
        dt = self.unwrapped.config.dt
        return [high_frequency_share(r[warmup_steps:ep["n_steps"], i], dt) for i, ep in enumerate(episodes)]

    def __init__(self, env: Any, n: int) -> None:
        self.env, self.unwrapped = env, env.unwrapped
        self.returns = np.zeros(n)
        self.alive = np.ones(n, bool)
        self.rates: list[np.ndarray] = []  # each step's applied rate commands, (n, 2) deg/s

    def reset(self, **kwargs: Any) -> Any:
        self.returns[:] = 0.0
        self.alive[:] = True
        self.rates = []
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        obs, rew, term, trunc, info = self.env.step(action)
        self.rates.append(np.stack([np.asarray(info["rate_command_az_deg_s"], float).reshape(-1),
                                    np.asarray(info["rate_command_el_deg_s"], float).reshape(-1)], 1))
        rew = np.asarray(rew, float).reshape(self.returns.shape)
        self.returns[self.alive] += rew[self.alive]
        self.alive &= ~np.asarray(term, bool).reshape(self.returns.shape)
        return obs, rew, term, trunc, info


def task_env(task: EvalTask, n: int | None = None) -> Any:
    """A DSS14 task's environment: the single one (``n`` None; a controller is built on it),
    or the vector environment of ``n`` rows (its episodes run there).
    """
    kw = {**PRESETS[task.preset].kwargs, **task.env_kwargs}
    kw.pop("max_episode_steps", None)
    if n is not None:
        from dss14_env.envs.vector import DSS14VectorEnv
        return DSS14VectorEnv(num_envs=n, **kw)
    from dss14_env.envs.env import DSS14Env
    return DSS14Env(**kw)


def _task_steps(task: EvalTask, steps: int | None) -> int:
    if steps is not None:
        return int(steps)
    if task.steps is not None:
        return int(task.steps)
    return int(task.env_kwargs.get("max_episode_steps", PRESETS[task.preset].max_episode_steps))


def _run_bench_task(ctrl: Any, task: EvalTask, seeds: Sequence[int], steps: int | None,
                    n_episodes: int) -> dict[str, Any]:
    """A DSS14 task through the shared episode loop (see :func:`run_task`)."""
    from dss14_env.baselines.rollout import SequentialDriver, batch_driver, run_rows

    n_steps = _task_steps(task, steps)
    seeds = [int(s) for s in seeds]
    driver = batch_driver(ctrl)
    episodes, returns, hf = [], [], []
    if driver is not None:
        env = _Returns(task_env(task, len(seeds)), len(seeds))
        groups = [(env, seeds)]
    else:
        driver = SequentialDriver(ctrl)
        groups = [(_Returns(task_env(task), 1), [s]) for s in seeds]
    try:
        if hasattr(ctrl, "target_env"):
            ctrl.target_env(groups[0][0].env)
        warmup_s = task.warmup_steps * groups[0][0].unwrapped.config.dt
        for k in range(n_episodes):
            for env, rows in groups:
                eps = run_rows(driver, env, rows, n_steps, warmup_s, reseed=k == 0)
                episodes += eps
                returns.append(env.returns.copy())
                hf += env.hf_shares(eps, task.warmup_steps)
    finally:
        for env, _ in groups:
            env.env.close()
    out = {key: np.array([_figure(ep, path) for ep in episodes]) for key, path in FIGURES.items()}
    out.update({"returns": np.concatenate(returns),
                "lengths": np.array([ep["n_steps"] for ep in episodes], np.int64),
                "terminated": np.array([ep["terminated"] for ep in episodes], bool),
                "command_hf_share": np.array(hf, float),
                "three_sigma_mdeg": out[f"servo_three_sigma_mdeg_{task.axis}"] if task.axis
                else np.full(len(episodes), np.nan),
                "pointing_three_sigma_mdeg": out[f"pointing_three_sigma_mdeg_{task.pointing_axis}"]
                if task.pointing_axis else np.full(len(episodes), np.nan),
                "episodes": episodes})
    return out


def _figure(ep: Mapping[str, Any], path: tuple[str, ...]) -> float:
    """One figure of an episode record (NaN where it has none; a 3σ of fewer than two scored
    steps is NaN already, :meth:`dss14_env.core.results.ErrorStats.of`).
    """
    v: Any = ep
    for key in path:
        if not isinstance(v, Mapping) or v.get(key) is None:
            return math.nan
        v = v[key]
    return float(v)


def _run_gym_task(ctrl: Any, task: EvalTask, seeds: Sequence[int], steps: int | None,
                  n_episodes: int) -> dict[str, Any]:
    """Any other environment: one per seed, stepped in lockstep through ``act_batch``."""
    kw = dict(task.env_kwargs)
    if steps is not None or task.steps is not None:
        kw["max_episode_steps"] = int(steps if steps is not None else task.steps)
    envs = [gym.make(task.env_id, **kw) for _ in seeds]
    if hasattr(ctrl, "target_env"):
        ctrl.target_env(envs[0])
    rets, lens, terms = [], [], []
    try:
        for k in range(n_episodes):
            obs = np.stack([e.reset(seed=int(s) if k == 0 else None)[0]
                            for e, s in zip(envs, seeds, strict=True)])
            n = len(envs)
            ctrl.reset_batch(n)
            done = np.zeros(n, bool)
            ret, length = np.zeros(n), np.zeros(n, np.int64)
            term = np.zeros(n, bool)
            while not done.all():
                act = ctrl.act_batch(obs)
                for i in np.flatnonzero(~done).tolist():
                    o, r, te, tr, _ = envs[i].step(act[i])
                    obs[i] = o
                    ret[i] += float(r)
                    length[i] += 1
                    if te or tr:
                        done[i] = True
                        term[i] = bool(te)
            rets.append(ret)
            lens.append(length)
            terms.append(term)
    finally:
        for e in envs:
            e.close()
    n_total = n_episodes * len(seeds)
    out: dict[str, Any] = {key: np.full(n_total, np.nan) for key in FIGURES}
    out.update({"returns": np.concatenate(rets), "lengths": np.concatenate(lens),
                "three_sigma_mdeg": np.full(n_total, np.nan),
                "pointing_three_sigma_mdeg": np.full(n_total, np.nan),
                "command_hf_share": np.full(n_total, np.nan),
                "terminated": np.concatenate(terms), "episodes": []})
    return out


def check_seed_protocol(seed: int, n_envs: int, eval_seeds: Sequence[int], source: str) -> None:
    """Refuse DSS14 training seeds or validation seeds outside their ranges (module doc).

    :raises ValueError: naming the key and ``source``
    """
    if seed < TRAINING_SEED_START:
        raise ValueError(f"{source}: key 'seed': DSS14 training seeds start at "
                         f"{TRAINING_SEED_START} (seeds 0-999 are the test seeds, 1000-9999 the "
                         f"validation seeds), got {seed}")
    lo, hi = VALIDATION_SEED_RANGE
    bad = [s for s in eval_seeds if not lo <= s < hi]
    if bad:
        raise ValueError(f"{source}: key 'eval_seeds': validation seeds are {lo}-{hi - 1} (never "
                         f"the test or training seeds), got {bad}")


__all__ = ["DEFAULT_SCENARIOS", "DSS14_TASKS", "EvalTask", "FIGURES", "FINAL_SCORING", "FinalScoring",
           "POINTING_AXIS_OF", "RESEARCH_SEEDS", "SCENARIO_TASKS", "SealedSeedError",
           "TEST_SEEDS", "TEST_SEED_RANGE", "TEST_STEPS", "TRAINING_SEED_START", "VALIDATION_SEED_RANGE",
           "check_seed_protocol", "check_unsealed", "dss14_tasks", "run_task",
           "task_env"]
