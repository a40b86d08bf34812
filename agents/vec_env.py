"""A stable-baselines3 ``VecEnv`` over the numpy-batched DSS14 vector environment.

SB3's ``DummyVecEnv`` steps N Python environments one after another; here ONE
:class:`dss14_env.envs.vector.DSS14VectorEnv` steps all N with a matrix product, so the
rollout costs a few microseconds per environment step instead of tens.

* :class:`SameStepDSS14VectorEnv` -- the vector environment with gymnasium's
  ``AutoresetMode.SAME_STEP``: a sub-environment that terminates or truncates is reset in the
  same ``step()``; the returned row is the new episode's first observation and the finished
  episode's last one is in ``info["final_obs"]`` (mask ``info["_final_obs"]``).  The draws and
  their order are the parent's (sub-environment ``i`` equals ``DSS14Env`` reset with
  ``seed + i`` and then auto-reset with ``reset()``); the reset only moves one call earlier.
  SB3 needs this: its ``VecEnv`` returns the next episode's first observation on the step
  that ends an episode (the parent's NEXT_STEP mode spends one extra call on the reset).
* :class:`SB3VecEnv` -- the SB3 ``VecEnv`` API over any gymnasium ``VectorEnv`` in SAME_STEP
  mode, as ``DummyVecEnv`` does it: ``dones = terminated | truncated``,
  ``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` on done
  steps, float32 rewards, SB3's ``seed()`` / ``set_options()`` protocol (used at the next
  ``reset()``).  Per-step info keys are copied into the per-environment dicts only when asked
  (``info_keys``): 16 keys x N dicts every step would cost more than the physics.
* :class:`InterfaceVecEnv` -- an SB3 ``VecEnvWrapper`` that shows the policy its
  :class:`~dss14_env.agents.interface.PolicyInterface` view of the rows.

The module subclasses SB3's classes and so imports stable-baselines3 (and torch); the rest of
:mod:`dss14_env.agents` imports it only where a training VecEnv is built.

:func:`make_subproc_vec_env` is SB3's ``SubprocVecEnv`` whose worker processes ignore SIGINT: a
terminal's Ctrl-C goes to the whole foreground process group, and workers killed by it would
end the training with their tracebacks and an ``EOFError`` instead of the main process's one
stop (a checkpoint where it stopped, :func:`dss14_env.agents.train.train`).

``make_sb3_vec_env(env_id, n_envs, seed=s)`` seeds sub-environment ``i`` with ``s + i`` (SB3's
``make_vec_env`` convention; ``PPO(seed=s)`` re-seeds a VecEnv the same way), so its episodes
are those of ``make_vec_env(env_id, n_envs, seed=s)`` with ``DummyVecEnv`` (tested up to the
vector environment's rounding, about 1e-10 relative).  It works under ``VecMonitor`` and
``VecNormalize``.
"""

from __future__ import annotations

import contextlib
import functools
import math
import multiprocessing
import signal
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from dss14_env.agents.envs import is_dss14_id
from dss14_env.agents.interface import LQG_BASES, InterfaceSpec, PolicyInterface, interface_observation_space
from dss14_env.envs.core import as_actions
from dss14_env.envs.vector import DSS14VectorEnv


def _vec_env_base() -> type:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    return VecEnv


class SameStepDSS14VectorEnv(DSS14VectorEnv):
    """:class:`DSS14VectorEnv` with ``AutoresetMode.SAME_STEP`` (see the module docstring).

    Built on the parent's per-row reset (its own episode draws); when the vector environment
    offers SAME_STEP itself this class is no longer needed.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        obs, reward, terminated, truncated, info = super().step(actions)
        done = terminated | truncated
        if done.any():
            idx = np.flatnonzero(done)
            final = np.zeros_like(obs)
            final[idx] = obs[idx]
            info["final_obs"], info["_final_obs"] = final, done.copy()
            obs[idx] = self.reset_now(idx)  # the draws the parent makes one call later
        return obs, reward, terminated, truncated, info


class SB3VecEnv(_vec_env_base()):
    """SB3 ``VecEnv`` over a gymnasium ``VectorEnv`` with SAME_STEP autoreset.

    :param venv: the vector environment (``metadata["autoreset_mode"]`` must be SAME_STEP)
    :param info_keys: keys of the vector info copied into ``infos[i]`` every step (default
        none: only ``terminal_observation`` / ``TimeLimit.truncated`` on done steps)
    :raises ValueError: for a vector environment in another autoreset mode
    """

    def __init__(self, venv: gym.vector.VectorEnv, info_keys: Iterable[str] = ()) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"SB3VecEnv needs a vector env with SAME_STEP autoreset, got {mode!r} "
                             "(use SameStepDSS14VectorEnv)")
        self.venv = venv
        self.info_keys = tuple(info_keys)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    # ---------------------------------------------------------------- core API
    def reset(self) -> np.ndarray:
        seeds = list(self._seeds)
        seed: Any = None if all(s is None for s in seeds) else seeds
        options = self._options[0] if self._options and self._options[0] else None
        obs, _ = self.venv.reset(seed=seed, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return np.asarray(obs, np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.num_envs, -1)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rew, term, trunc, info = self.venv.step(self._actions)
        dones = term | trunc
        cols = [(k, info[k]) for k in self.info_keys if k in info]
        infos: list[dict] = [{k: v[i] for k, v in cols} for i in range(self.num_envs)]
        if dones.any():
            final = info["final_obs"]
            for i in np.flatnonzero(dones).tolist():
                infos[i]["terminal_observation"] = np.asarray(final[i], np.float32)
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
        return np.asarray(obs, np.float32), np.asarray(rew, np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    # ---------------------------------------------------------------- attribute access
    # one batched env: attributes are the vector env's, the same for every index
    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list[Any]:
        r = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [r] * len(self._get_indices(indices))

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs


class MixtureVecEnv(_vec_env_base()):
    """One SB3 ``VecEnv`` over several (a mixture of scenarios: tracks, holds, steps, slews in
    one rollout): their sub-environments side by side, in the order given.

    Seeding keeps SB3's convention over the whole: sub-environment ``i`` of the mixture is seeded
    ``seed + i`` (part ``j`` gets ``seed + offset_j``), so no two sub-environments share a seed.
    The parts must have the same observation and action spaces.

    :param parts: the VecEnvs (e.g. :class:`SB3VecEnv` of different DSS14 presets)
    :param names: a label per part (attribute ``part_names``; ``get_attr("scenario_name")``)
    :raises ValueError: no parts, or parts with different spaces
    """

    def __init__(self, parts: Sequence[Any], names: Sequence[str] | None = None) -> None:
        if not parts:
            raise ValueError("a mixture needs at least one VecEnv")
        first = parts[0]
        for p in parts[1:]:
            if p.observation_space != first.observation_space or p.action_space != first.action_space:
                raise ValueError("the parts of a mixture must have the same observation and action spaces")
        self.parts = list(parts)
        self.part_names = list(names) if names is not None else [str(i) for i in range(len(parts))]
        self._bounds = np.cumsum([0] + [p.num_envs for p in self.parts])
        super().__init__(int(self._bounds[-1]), first.observation_space, first.action_space)

    def _slices(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in zip(self._bounds[:-1], self._bounds[1:], strict=True)]

    def reset(self) -> np.ndarray:
        for p, sl in zip(self.parts, self._slices(), strict=True):
            seeds = self._seeds[sl]
            if all(s is not None for s in seeds):
                p.seed(int(seeds[0]))
        self._reset_seeds()
        self._reset_options()
        return np.concatenate([p.reset() for p in self.parts])

    def step_async(self, actions: np.ndarray) -> None:
        a = np.asarray(actions)
        for p, sl in zip(self.parts, self._slices(), strict=True):
            p.step_async(a[sl])

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        out = [p.step_wait() for p in self.parts]
        return (np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out]),
                np.concatenate([o[2] for o in out]), [i for o in out for i in o[3]])

    def close(self) -> None:
        for p in self.parts:
            p.close()

    def _part_indices(self, indices: Any) -> list[tuple[int, int]]:
        """``(part, index within the part)`` of each global index."""
        idx = np.asarray(list(self._get_indices(indices)), int)
        part = np.searchsorted(self._bounds, idx, side="right") - 1
        return [(int(j), int(i - self._bounds[j])) for i, j in zip(idx, part, strict=True)]

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        if attr_name == "scenario_name":
            return [self.part_names[j] for j, _ in self._part_indices(indices)]
        return [self.parts[j].get_attr(attr_name, [k])[0] for j, k in self._part_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        for j, k in self._part_indices(indices):
            self.parts[j].set_attr(attr_name, value, [k])

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list[Any]:
        return [self.parts[j].env_method(method_name, *method_args, indices=[k], **method_kwargs)[0]
                for j, k in self._part_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs


def _vec_env_wrapper() -> type:
    from stable_baselines3.common.vec_env import VecEnvWrapper

    return VecEnvWrapper


class ActionChangePenaltyVecEnv(_vec_env_wrapper()):
    """Training rewards minus ``weight * ||a[k] - a[k-1]||^2`` of the environment's actions
    (action units: what the environment receives, base controller and residual together),
    nothing on an episode's first step.

    The environment's own action-change weight also sets its model-based controllers' designs
    (:class:`dss14_env.baselines.interface.Weights`: raising it makes a residual's base LQG
    another, slower design); this penalty smooths the learned command without touching them.

    :param venv: the VecEnv (DSS14 actions and rewards)
    :param weight: the penalty's weight (>= 0)
    """

    def __init__(self, venv: Any, weight: float) -> None:
        super().__init__(venv)
        if not (math.isfinite(weight) and weight >= 0.0):
            raise ValueError(f"action-change penalty weight must be finite and >= 0, got {weight!r}")
        self.weight = float(weight)
        self._actions = np.zeros((self.num_envs, 2))
        self._prev = np.zeros((self.num_envs, 2))
        self._fresh = np.ones(self.num_envs, bool)

    def reset(self) -> np.ndarray:
        self._fresh[:] = True
        return self.venv.reset()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, np.float64).reshape(self.num_envs, -1).copy()
        self.venv.step_async(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rew, dones, infos = self.venv.step_wait()
        a = self._actions
        change = np.where(self._fresh[:, None], 0.0, a - self._prev)
        out = np.asarray(rew, np.float64) - self.weight * np.sum(change * change, axis=1)
        self._prev = a
        self._fresh = np.asarray(dones, bool).copy()
        return obs, out.astype(np.float32), dones, infos


class LogRewardVecEnv(_vec_env_wrapper()):
    """Training rewards ``-log(1 + c / scale)`` of the environment's per-step cost ``c`` (its
    reward's negative without the termination penalty), and on a terminating step minus a
    penalty no episode can gain by: ``log(1 + c_max / scale) / (1 - gamma)``, the discounted
    sum of the largest per-step value before termination.

    On a mixture the errors of steps and slews (100 mdeg: cost 100) and of holds (1 mdeg: cost
    0.01) differ by four decades; the logarithm keeps every scenario's errors in the gradient
    (a hold's 1-mdeg improvement moves the reward as much as a step's 30 %).  Episode returns
    logged by a ``VecMonitor`` below it stay the environment's.

    :param venv: the VecEnv (DSS14 rewards)
    :param scale: the cost at which the logarithm bends (e.g. 0.01: 1 mdeg of error at
        ``error_scale_mdeg`` 10)
    :param env_config: the environment's configuration (termination penalty, error bound,
        action-change weight)
    :param gamma: the discount of the learner
    :param action_change_penalty: the weight of an :class:`ActionChangePenaltyVecEnv` below, whose
        penalty is part of ``c`` (it bounds ``c_max`` too)
    """

    def __init__(self, venv: Any, scale: float, env_config: Any, gamma: float,
                 action_change_penalty: float = 0.0) -> None:
        super().__init__(venv)
        self.scale = float(scale)
        self.penalty = float(env_config.termination_penalty)
        err = env_config.max_error_deg * 1.0e3 / env_config.error_scale_mdeg
        c_max = 2.0 * err * err + 8.0 * (env_config.action_change_weight + action_change_penalty)
        self.terminal = float(np.log1p(c_max / self.scale) / (1.0 - gamma))

    def reset(self) -> np.ndarray:
        return self.venv.reset()

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rew, dones, infos = self.venv.step_wait()
        term = np.array([bool(d and not i.get("TimeLimit.truncated", False))
                         for d, i in zip(dones, infos, strict=True)])
        cost = np.maximum(-np.asarray(rew, np.float64) - self.penalty * term, 0.0)
        out = -np.log1p(cost / self.scale) - self.terminal * term
        return obs, out.astype(np.float32), dones, infos


def make_sb3_vec_env(env_id: str = "DSS14-Hold-v0", n_envs: int = 8, seed: int | None = None,
                     max_episode_steps: int | None = None, info_keys: Iterable[str] = (),
                     **env_kwargs: Any) -> SB3VecEnv:
    """An :class:`SB3VecEnv` over :class:`SameStepDSS14VectorEnv` for a registered DSS14 id.

    :param env_id: a registered DSS14 id (its registration's kwargs and ``max_episode_steps``
        are used, as ``gymnasium.make_vec`` does)
    :param n_envs: sub-environments
    :param seed: sub-environment ``i`` is seeded with ``seed + i`` at the first reset (None:
        fresh entropy)
    :param max_episode_steps: override of the registration's episode length
    :param info_keys: see :class:`SB3VecEnv`
    :param env_kwargs: configuration keys laid over the registration's
    :raises ValueError: for an id that is not a DSS14 id
    """
    if not is_dss14_id(env_id):
        raise ValueError(f"{env_id!r} is not a DSS14 environment id (the batched VecEnv steps "
                         f"the DSS14 vector environment only); use vec_env: dummy")
    spec = gym.spec(env_id)
    kwargs = {**spec.kwargs, **env_kwargs}
    steps = max_episode_steps if max_episode_steps is not None else spec.max_episode_steps
    venv = SB3VecEnv(SameStepDSS14VectorEnv(n_envs, max_episode_steps=steps, **kwargs), info_keys)
    if seed is not None:
        venv.seed(seed)
    return venv


class InterfaceVecEnv(_vec_env_wrapper()):
    """An SB3 VecEnv of DSS14 environments (plain 12 observations) seen through a
    :class:`PolicyInterface` with one row per sub-environment.

    A done sub-environment's ``terminal_observation`` is turned into the policy's view of it
    (:meth:`PolicyInterface.peek`), then its row restarts on the new episode's first
    observation -- as :class:`InterfaceWrapper` inside a ``DummyVecEnv`` does.

    :param venv: the vector environment (``num_envs`` rows)
    :param spec: the interface
    :param env_config: the environment configuration
    """

    def __init__(self, venv: Any, spec: InterfaceSpec, env_config: Any) -> None:
        self.interface = PolicyInterface(spec, env_config, venv.num_envs)
        if spec.context or spec.base in LQG_BASES:  # each sub-environment's own configuration (a
            # mixture's parts differ: the context, and where an LQG base's encoders sit)
            self.interface.set_context(list(venv.get_attr("config")))
        super().__init__(venv, observation_space=interface_observation_space(self.interface),
                         action_space=spaces.Box(-1.0, 1.0, (2,), np.float32))

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        self.interface.reset()
        return self.interface.observe(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(self.interface.action(as_actions(actions, (self.num_envs, 2))))

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rew, dones, infos = self.venv.step_wait()
        if dones.any():
            idx = np.flatnonzero(dones)
            term = np.stack([infos[i]["terminal_observation"] for i in idx.tolist()])
            feats = self.interface.peek(term, idx)
            for k, i in enumerate(idx.tolist()):
                infos[i]["terminal_observation"] = feats[k]
            self.interface.restart(dones)
        return self.interface.observe(obs), rew, dones, infos


def _ignoring_sigint(factory: Callable[[], Any]) -> Any:
    """Build a worker's environment with SIGINT ignored in the worker (run there, by SB3)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return factory()


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Context manager: SIGINT ignored in this (main) thread's process for the block, so that a
    process started in it inherits the ignored signal from birth; elsewhere than in the main
    thread (a Ray task's thread) nothing changes.
    """
    try:
        before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not this thread's to set
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def make_subproc_vec_env(env_fns: Sequence[Callable[[], Any]], **kwargs: Any) -> Any:
    """SB3's ``SubprocVecEnv`` over ``env_fns`` whose workers ignore SIGINT (see the module doc):
    only the main process handles a Ctrl-C, and closes the workers.

    The workers are forked by multiprocessing's fork server, started here (if it is not
    running yet) with SIGINT ignored for the milliseconds it takes, so that every worker
    ignores it from birth; each worker also ignores it as it builds its environment (a fork
    server started earlier by other code).  Pass as ``vec_env_cls`` of SB3's ``make_vec_env``.

    :param kwargs: ``SubprocVecEnv``'s (``start_method`` is chosen here)
    """
    from stable_baselines3.common.vec_env import SubprocVecEnv

    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    if method == "forkserver":
        from multiprocessing import forkserver

        with _sigint_ignored():
            forkserver.ensure_running()
    kwargs.pop("start_method", None)
    return SubprocVecEnv([functools.partial(_ignoring_sigint, fn) for fn in env_fns],
                         start_method=method, **kwargs)


__all__ = ["ActionChangePenaltyVecEnv", "InterfaceVecEnv", "LogRewardVecEnv", "MixtureVecEnv", "SB3VecEnv",
           "SameStepDSS14VectorEnv", "make_sb3_vec_env", "make_subproc_vec_env"]
