"""Evaluation of trained policies on seeds never seen in training.

Seed protocol of the DSS14 runs (checked when training starts):

* **test** seeds 0-999: the benchmark's; the final evaluation uses :data:`TEST_SEEDS` (0-9);
* **validation** seeds 1000-9999: the periodic evaluation during training (``eval_seeds``),
  which picks ``eval/best``;
* **training** seeds 10 000 and up: sub-environment ``i`` of a run with ``seed`` s starts
  from ``s + i``.

The tasks of a DSS14 run are the benchmark's hold scenarios (:data:`DSS14_TASKS`): 50 km/h
front wind scored on elevation, side wind on azimuth (the axis the wind loads), 3σ of the
servo error after the 5-s warm-up, in mdeg, the report's Table 4 figure; beside it the 3σ of
the dish's true pointing error on the axis the wind swings (front: elevation, side:
cross-elevation; the environment's ``pointing_error_*_mdeg``, as the benchmark's runner
scores it).  For any other environment the one task is the configured environment and the
score its return.

Episodes of all seeds run in lockstep through one controller's batched API
(:meth:`dss14_env.agents.policy.PolicyController.act_batch`), one environment per seed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from dss14_env.core.results import ErrorStats
from dss14_env.envs.config import load_env_config
from dss14_env.envs.presets import PRESETS

#: the seed ranges of the protocol (see the module doc)
TEST_SEED_RANGE = (0, 1000)
VALIDATION_SEED_RANGE = (1000, 10_000)
TRAINING_SEED_START = 10_000
#: the final evaluation: test seeds and episode length (60 s at 50 Hz)
TEST_SEEDS = tuple(range(10))
TEST_STEPS = 3000
#: the pointing-error axis swung with each loaded drive axis: elevation, cross-elevation
POINTING_AXIS_OF = {"el": "el", "az": "xel"}


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
    """

    name: str
    env_id: str
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    axis: str | None = None
    warmup_steps: int = 0
    pointing_axis: str | None = None


def dss14_tasks(env_kwargs: Mapping[str, Any] | None = None) -> list[EvalTask]:
    """The benchmark's scenarios with one loaded axis (the presets' ``loaded_axes``: the hold
    scenarios) as evaluation tasks, with ``env_kwargs`` laid over; the warm-up in steps of the
    environment's ``dt``; the pointing error scored on the axis the wind swings
    (:data:`POINTING_AXIS_OF`).
    """
    kw = dict(env_kwargs or {})
    dt = float(kw["dt"]) if "dt" in kw else load_env_config().dt
    return [EvalTask(name, p.env_id, kw, p.loaded_axes[0], int(round(p.warmup_s / dt)),
                     POINTING_AXIS_OF[p.loaded_axes[0]])
            for name, p in PRESETS.items() if len(p.loaded_axes) == 1]


#: the DSS14 evaluation tasks: hold in 50 km/h front wind (elevation), side wind (azimuth)
DSS14_TASKS = tuple(dss14_tasks())


def run_task(ctrl: Any, task: EvalTask, seeds: Sequence[int], steps: int | None = None,
             n_episodes: int = 1) -> dict[str, np.ndarray]:
    """Run the controller's deterministic policy on one task.

    For every seed the first episode starts with ``reset(seed=seed)``, the next
    ``n_episodes - 1`` continue the environment's generator.

    :param ctrl: a batchable controller (``reset_batch``, ``act_batch``)
    :param task: the task
    :param seeds: one environment per seed
    :param steps: episode length (``max_episode_steps``), default None: the environment's
    :param n_episodes: episodes per seed
    :return: ``returns``, ``lengths``, ``three_sigma_mdeg`` (NaN without an axis),
        ``pointing_three_sigma_mdeg`` (NaN without a pointing axis), ``terminated`` -- arrays
        of ``n_episodes * len(seeds)`` (episode-major)
    """
    kw = dict(task.env_kwargs)
    if steps is not None:
        kw["max_episode_steps"] = int(steps)
    envs = [gym.make(task.env_id, **kw) for _ in seeds]
    if hasattr(ctrl, "target_env"):
        ctrl.target_env(envs[0])
    keys = {"servo": None if task.axis is None else f"servo_error_{task.axis}_mdeg",
            "pointing": None if task.pointing_axis is None else f"pointing_error_{task.pointing_axis}_mdeg"}
    rets, lens, terms = [], [], []
    sig: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    try:
        for k in range(n_episodes):
            obs = np.stack([e.reset(seed=int(s) if k == 0 else None)[0]
                            for e, s in zip(envs, seeds, strict=True)])
            n = len(envs)
            ctrl.reset_batch(n)
            done = np.zeros(n, bool)
            ret, length = np.zeros(n), np.zeros(n, np.int64)
            term = np.zeros(n, bool)
            errors = {k: [[] for _ in range(n)] for k, v in keys.items() if v is not None}
            while not done.all():
                act = ctrl.act_batch(obs)
                for i in np.flatnonzero(~done).tolist():
                    o, r, te, tr, info = envs[i].step(act[i])
                    obs[i] = o
                    ret[i] += float(r)
                    length[i] += 1
                    if length[i] > task.warmup_steps:
                        for k, rows in errors.items():
                            rows[i].append(float(info[keys[k]]))
                    if te or tr:
                        done[i] = True
                        term[i] = bool(te)
            rets.append(ret)
            lens.append(length)
            terms.append(term)
            for k in keys:
                sig[k].append(_three_sigma(errors.get(k), n))
    finally:
        for e in envs:
            e.close()
    return {"returns": np.concatenate(rets), "lengths": np.concatenate(lens),
            "three_sigma_mdeg": np.concatenate(sig["servo"]),
            "pointing_three_sigma_mdeg": np.concatenate(sig["pointing"]),
            "terminated": np.concatenate(terms)}


def _three_sigma(rows: list[list[float]] | None, n: int) -> np.ndarray:
    """3σ (:class:`~dss14_env.core.results.ErrorStats`) of each row's errors; NaN for rows of
    fewer than two values or when nothing was recorded (``rows`` None).
    """
    if rows is None:
        return np.full(n, np.nan)
    return np.array([ErrorStats.of(e).three_sigma if len(e) > 1 else np.nan for e in rows])


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


__all__ = ["DSS14_TASKS", "EvalTask", "POINTING_AXIS_OF", "TEST_SEEDS", "TEST_SEED_RANGE", "TEST_STEPS",
           "TRAINING_SEED_START", "VALIDATION_SEED_RANGE", "check_seed_protocol", "dss14_tasks",
           "run_task"]
