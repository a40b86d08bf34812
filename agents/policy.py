"""A trained PPO policy behind the shared controller interface, and a small evaluation helper.

:class:`PPOController` loads ``model.zip`` + ``vecnormalize.pkl`` (a run folder, its
``eval/best/`` folder, or a checkpoint zip), normalises each observation with the *frozen*
training statistics and returns the deterministic (mean) action::

    from dss14_env.agents.policy import load_policy, evaluate
    ctrl = load_policy("runs/ppo-20250101-120000")   # or load_policy(): the shipped policy
    ctrl.reset(seed=0)
    action = ctrl.act(obs)            # shape of the action space, clipped to its bounds
    ctrl.info["inference_time_s"]     # wall time of the last act()

    evaluate("runs/ppo-20250101-120000", seeds=[0, 1, 2], n_episodes=1)
"""

from __future__ import annotations

import pickle
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dss14_env.agents.ppo import PPOConfig, make_env, vecnormalize_path_for
from dss14_env.baselines.base import Controller

#: the policy shipped with the package (docs/ppo.md: how it was trained, how to reproduce it)
DEFAULT_POLICY = Path(__file__).resolve().parent / "policies" / "residual_pi"


def _model_paths(path: str | Path) -> tuple[Path, Path]:
    """(model zip, VecNormalize pickle) for a folder or a zip path."""
    p = Path(path)
    if p.is_dir():
        model = p / "model.zip"
    elif p.suffix == ".zip":
        model = p
    elif p.with_suffix(".zip").is_file():  # SB3 style: the path without .zip
        model = p.with_suffix(".zip")
    else:
        raise ValueError(f"no PPO policy at {p}: expected a folder with model.zip or a .zip file")
    if not model.is_file():
        raise ValueError(f"PPO model not found: {model}")
    stats = vecnormalize_path_for(model)
    if not stats.is_file():
        raise ValueError(f"VecNormalize stats of {model} not found: {stats}")
    return model, stats


class PPOController(Controller):
    """Deterministic PPO policy with frozen observation normalisation.

    :param path: run folder, ``eval/best`` folder (both with ``model.zip`` and
        ``vecnormalize.pkl``), or a model/checkpoint zip with its stats beside it
    :param name: label in tables and plots, default None: ``"PPO (<folder name>)"``
    :param torch_threads: ``torch.set_num_threads`` value (process-wide; one thread is fastest
        for small MLPs), default 1; None leaves torch alone
    :param env: the DSS14 environment the controller will act on, default None; only used by a
        residual policy (run trained on ``DSS14-Residual-v0``, :mod:`dss14_env.agents.residual`), whose PI
        takes the period and scales from it; None: the run's base environment

    A residual policy's controller composes ``PI + residual_scale * policy`` itself (the run's
    ``config.yaml`` names the gains and scale), so like every other controller it takes the
    environment's plain 12 observations.
    """

    def __init__(self, path: str | Path, name: str | None = None,
                 torch_threads: int | None = 1, env: Any = None) -> None:
        import torch
        from stable_baselines3 import PPO

        model_path, stats_path = _model_paths(path)
        run = model_path.parent
        if run.name == "checkpoints":
            run = run.parent
        super().__init__(name or f"PPO ({run.name})")
        if torch_threads is not None:
            torch.set_num_threads(torch_threads)
        self.model_path, self.stats_path = model_path, stats_path
        self.model = PPO.load(model_path, device="cpu")
        with open(stats_path, "rb") as fh:  # what VecNormalize.load does, without a venv
            self.vec_normalize = pickle.load(fh)
        self.vec_normalize.training = False  # frozen statistics
        self.vec_normalize.norm_reward = False
        self.observation_space = self.model.observation_space
        self.action_space = self.model.action_space
        self.config = _run_config(model_path)
        self.residual = _residual_core(self.config, env)
        if self.residual is not None and self.observation_space.shape != (self.residual.obs_dim,):
            raise ValueError(f"{model_path}: this residual run's policy must observe "
                             f"{self.residual.obs_dim} entries, got {self.observation_space.shape}")

    def reset(self, seed: int | None = None) -> None:
        """New episode (restarts a residual policy's PI).

        :param seed: unused (the policy is deterministic)
        """
        super().reset(seed)
        if self.residual is not None:
            self.residual.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Deterministic action for one observation.

        :param observation: one observation of the environment (not normalised)
        :return: the action, shape of the action space, clipped to its bounds
        """
        t0 = time.perf_counter()
        obs = np.asarray(observation, dtype=np.float32)
        expected = (12,) if self.residual is not None else self.observation_space.shape
        if obs.shape != expected:
            raise ValueError(f"{self.name}: observation shape {obs.shape}, the policy expects "
                             f"{expected}")
        if self.residual is not None:
            obs = self.residual.observe(obs)
        action, _ = self.model.predict(self.vec_normalize.normalize_obs(obs), deterministic=True)
        if self.residual is not None:
            action = self.residual.combine(action)
        dt = time.perf_counter() - t0
        # "solve_time_s" too, so that tables of solve times include the learned controller
        self.info = {"inference_time_s": dt, "solve_time_s": dt}
        return action


def load_policy(path: str | Path | None = None, env: Any = None,
                name: str | None = None) -> PPOController:
    """Load a trained PPO policy as a :class:`dss14_env.baselines.base.Controller`.

    :param path: run folder, ``eval/best`` folder, or a model/checkpoint zip; default None:
        the policy shipped with the package (:data:`DEFAULT_POLICY`)
    :param env: the environment it will act on (see :class:`PPOController`), default None
    :param name: label, default None (from the folder name)
    """
    return PPOController(DEFAULT_POLICY if path is None else path, name=name, env=env)


def _residual_core(cfg: PPOConfig | None, env: Any) -> Any:
    """The :class:`dss14_env.agents.residual.ResidualPI` of a residual run, else None."""
    from dss14_env.agents.residual import (
        DEFAULT_GAINS,
        DEFAULT_HISTORY,
        DEFAULT_RESIDUAL_SCALE,
        RESIDUAL_ENV_ID,
        ResidualPI,
        base_env_args,
    )

    if cfg is None or cfg.env_id != RESIDUAL_ENV_ID:
        return None
    kw = dict(cfg.env_kwargs)
    if env is None:
        env = make_env(*base_env_args(kw))
    gains = kw.get("gains", DEFAULT_GAINS)
    return ResidualPI(env, tuple(gains) if isinstance(gains, list) else gains,
                      kw.get("residual_scale", DEFAULT_RESIDUAL_SCALE),
                      kw.get("history", DEFAULT_HISTORY))


def _run_config(model_path: Path) -> PPOConfig | None:
    for d in (model_path.parent, model_path.parent.parent, model_path.parent.parent.parent):
        f = d / "config.yaml"
        if f.is_file():
            return PPOConfig.from_dict(yaml.safe_load(f.read_text()) or {}, source=str(f))
    return None


def evaluate(path: str | Path, env_id: str | None = None, seeds: Iterable[int] = (0,),
             n_episodes: int = 1, env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Mean and spread of the episode return of the deterministic policy (a quick check; the
    project's runner does the real scoring).

    For every seed the first episode starts with ``reset(seed=seed)``; the next
    ``n_episodes - 1`` continue the environment's generator (as the training-time evaluation
    does with ``eval_seeds`` and ``n_eval_episodes``).

    :param path: run folder, ``eval/best`` folder, or a model/checkpoint zip
    :param env_id: environment, default None: ``env_id`` of the run's ``config.yaml``
    :param seeds: episode seeds, default ``(0,)``
    :param n_episodes: episodes per seed, default 1
    :param env_kwargs: ``gymnasium.make`` arguments, default None: the run's (or none when
        ``env_id`` is given and differs from the run's)
    :return: ``mean_return``, ``std_return``, ``min_return``, ``max_return``, ``returns``,
        ``lengths``, ``n_episodes`` (total), ``seeds``, ``env_id``, ``mean_inference_time_s``

    A residual policy (trained on ``DSS14-Residual-v0``) composes its actions itself, so it
    is stepped on the base environment underneath (same episodes, same rewards).
    """
    ctrl = PPOController(path)
    cfg = _run_config(ctrl.model_path)
    if env_id is None:
        if cfg is None:
            raise ValueError(f"no config.yaml near {ctrl.model_path}: pass env_id")
        env_id = cfg.env_id
    env_module = cfg.env_module if cfg is not None else None
    if env_kwargs is None:
        env_kwargs = cfg.env_kwargs if cfg is not None and cfg.env_id == env_id else {}
    seeds = [int(s) for s in seeds]
    if not seeds or n_episodes < 1:
        raise ValueError("evaluate: need at least one seed and n_episodes >= 1")
    from dss14_env.agents.residual import RESIDUAL_ENV_ID, base_env_args

    if ctrl.residual is not None and env_id == RESIDUAL_ENV_ID:  # step the base environment
        env_id, env_kwargs = base_env_args(env_kwargs)
    env = make_env(env_id, env_kwargs, env_module)
    returns, lengths, times = [], [], []
    try:
        for seed in seeds:
            for k in range(n_episodes):
                obs, _ = env.reset(seed=seed if k == 0 else None)
                ctrl.reset(seed)
                ret, n, done = 0.0, 0, False
                while not done:
                    obs, r, term, trunc, _ = env.step(ctrl.act(obs))
                    times.append(ctrl.info["inference_time_s"])
                    ret += float(r)
                    n += 1
                    done = term or trunc
                returns.append(ret)
                lengths.append(n)
    finally:
        env.close()
    r = np.asarray(returns)
    return {"env_id": env_id, "seeds": seeds, "n_episodes": len(returns),
            "mean_return": float(r.mean()), "std_return": float(r.std()),
            "min_return": float(r.min()), "max_return": float(r.max()),
            "returns": [float(x) for x in r], "lengths": lengths,
            "mean_inference_time_s": float(np.mean(times))}


__all__ = ["DEFAULT_POLICY", "PPOController", "evaluate", "load_policy"]
