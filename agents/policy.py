"""A trained policy behind the shared controller interface, loaded without unpickling.

:func:`load_policy` reads a policy folder (:mod:`dss14_env.agents.storage`: ``policy.pt``,
``normalization.npz``, ``config.yaml``; a run folder, its ``eval/best/`` or a checkpoint
folder), rebuilds the network from the configuration, checks that weights and statistics
belong to the same run, and returns a :class:`PolicyController`: it normalises each
observation with the *frozen* training statistics and returns the deterministic action::

    from dss14_env.agents.policy import load_policy
    ctrl = load_policy("runs/ppo-20250101-120000", env=env)   # or load_policy(): the shipped one
    ctrl.reset(seed=0)
    action = ctrl.act(obs)            # shape (2,), in [-1, 1]
    ctrl.info["inference_time_s"]     # wall time of the last act()

The controller is batchable (the runner's vector path): ``reset_batch(n)``, ``act_batch(obs
(n, 12)) -> (n, 2)``, ``restart(mask)`` for rows whose sub-environment was reset,
``info_batch``.  A residual or model-informed policy composes its base controller (PI or
LQG) itself per row, a recurrent policy keeps one LSTM state per row; like every other
controller it takes the environment's plain 12 observations.

A foreign stable-baselines3 policy (``model.zip`` + ``vecnormalize.pkl``) is unpickled, which
can run code: it loads only with ``trust_pickle=True``.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.agents.algos import algo_class, build_policy, is_recurrent
from dss14_env.agents.config import TrainConfig, load_config
from dss14_env.agents.envs import make_env, resolve_env
from dss14_env.agents.interface import InterfaceSpec, PolicyInterface
from dss14_env.agents.storage import (
    NormStats,
    PolicyFileError,
    PolicyFiles,
    check_fingerprints,
    find_policy_files,
    load_sb3_model,
    load_stats,
    load_weights,
    policy_problem,
)
from dss14_env.baselines.base import Controller
from dss14_env.baselines.scheduled import check_readings
from dss14_env.core.schema import read_config
from dss14_env.envs.core import OBS_HIGH

#: the folder of the policies shipped with the package (docs/rl.md: how each was trained and
#: selected, its results, how to reproduce it)
POLICIES_DIR = Path(__file__).resolve().parent / "policies"
#: the policy :func:`load_policy` loads without a path
DEFAULT_POLICY = POLICIES_DIR / "residual_pi"


def shipped_policies() -> list[str]:
    """Names of the shipped policies (folders of :data:`POLICIES_DIR`)."""
    return sorted(d.name for d in POLICIES_DIR.iterdir() if (d / "policy.pt").is_file())


def shipped_policy(name: str) -> Path:
    """The folder of a shipped policy (``load_policy(shipped_policy("ppo_plain"))``).

    :raises ValueError: an unknown name, naming the shipped ones
    """
    names = shipped_policies()
    if name not in names:
        raise ValueError(f"no shipped policy {name!r}; shipped: {', '.join(names)}")
    return POLICIES_DIR / name
#: labels of the algorithms in controller names
ALGO_LABELS = {"ppo": "PPO", "recurrent_ppo": "RecurrentPPO", "sac": "SAC"}


def _env_config(env: Any) -> Any:
    return getattr(getattr(env, "unwrapped", env), "config", None)


def is_gaussian_mlp(policy: Any) -> bool:
    """Whether ``policy`` is stable-baselines3's plain ``ActorCriticPolicy`` (PPO's
    ``MlpPolicy``): flattened observations through linear layers and activations, a diagonal
    Gaussian on unsquashed Box actions -- what :func:`gaussian_mlp_actions` acts for.
    """
    from gymnasium import spaces
    from stable_baselines3.common.distributions import DiagGaussianDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor

    return (type(policy) is ActorCriticPolicy and type(policy.pi_features_extractor) is FlattenExtractor
            and isinstance(policy.action_dist, DiagGaussianDistribution) and not policy.squash_output
            and isinstance(policy.action_space, spaces.Box)
            and isinstance(policy.observation_space, spaces.Box))


def gaussian_mlp_actions(policy: Any, x: np.ndarray) -> np.ndarray:
    """The deterministic actions of a plain Gaussian MLP policy (:func:`is_gaussian_mlp`) for
    float32 observations ``x (n, obs_dim)``: the mean of its Gaussian, clipped to the action
    space -- the very operations of its ``predict(x, deterministic=True)``, without building the
    distribution object (equal to it bit for bit).
    """
    import torch
    from stable_baselines3.common.policies import BaseModel

    with torch.no_grad():
        features = BaseModel.extract_features(policy, torch.as_tensor(x), policy.pi_features_extractor)
        mean = policy.action_net(policy.mlp_extractor.forward_actor(features))
    u = mean.numpy().reshape((-1, *policy.action_space.shape))
    return np.clip(u, policy.action_space.low, policy.action_space.high)


class PolicyController(Controller):
    """Deterministic trained policy with frozen observation normalisation (see the module doc).

    :param policy: the SB3 policy network (``predict``)
    :param config: the run's configuration (algorithm, environment, interface), or None for a
        foreign policy without one (then it acts on the raw observations)
    :param stats: frozen observation statistics, or None
    :param name: label in tables and plots
    :param env: the environment it will act on, default None: the run's; a residual or
        model-informed policy's base controller is designed for the *training* environment
        with ``env``'s encoder placement (:meth:`PolicyInterface.set_context`), and actions are
        converted to ``env``'s action scale
    :param torch_threads: ``torch.set_num_threads`` value (process-wide), default 1; None leaves
        torch alone
    """

    batchable = True

    def __init__(self, policy: Any, config: TrainConfig | None, stats: NormStats | None,
                 name: str, env: Any = None, torch_threads: int | None = 1) -> None:
        import torch

        super().__init__(name)
        if torch_threads is not None:
            torch.set_num_threads(torch_threads)
        self.policy, self.config, self.stats = policy, config, stats
        self.recurrent = config is not None and is_recurrent(config.algo)
        #: the network is a plain Gaussian MLP policy: :func:`gaussian_mlp_actions` acts for it
        self.gaussian_mlp = not self.recurrent and is_gaussian_mlp(policy)
        self.obs_dim = int(np.prod(policy.observation_space.shape))
        self.spec: InterfaceSpec | None = None
        self.train_env_config = None
        #: the configuration of the environment it acts on (:meth:`target_env`; None: the run's)
        self.target_config = None
        self.to_env = 1.0
        if config is not None:
            plan = resolve_env(config)
            self.spec = plan.interface
            if plan.dss14:
                base = make_env(plan.base_id, plan.base_kwargs)
                self.train_env_config = _env_config(base)
                base.close()
        self.input_dim = 12 if self.spec is not None else self.obs_dim
        if env is not None:
            self.target_env(env)
        self.info_batch: dict[str, np.ndarray] = {}
        #: the mean wind speed reading of :meth:`set_scenario` (m/s), kept over episodes
        self._reading: float | None = None
        self.reset_batch(1)
        if self.interface is not None and self.interface.obs_dim != self.obs_dim:
            raise PolicyFileError(f"{config.source}: the interface of env_id "
                                  f"{config.env_id!r} gives {self.interface.obs_dim} observations, "
                                  f"the weights expect {self.obs_dim}")

    def target_env(self, env: Any) -> None:
        """Act on ``env`` from now on: actions are converted from the training environment's
        action scale to ``env``'s (a DSS14 environment; others are left alone).
        """
        target = _env_config(env)
        if self.train_env_config is not None and target is not None:
            self.to_env = self.train_env_config.action_scale_deg_s / target.action_scale_deg_s
            self.target_config = target
            if getattr(self, "interface", None) is not None:
                self.interface.set_context(target)

    # ------------------------------------------------------------------ single
    def reset(self, seed: int | None = None) -> None:
        """New episode (restarts a base controller, history and LSTM state).

        :param seed: unused (the policy is deterministic)
        """
        super().reset(seed)
        self.reset_batch(1)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Deterministic action for one observation (the environment's, not normalised).

        :raises ValueError: wrong shape or non-finite observation
        """
        obs = np.asarray(observation, dtype=np.float32)
        if obs.shape != (self.input_dim,):
            raise ValueError(f"{self.name}: observation shape {obs.shape}, the policy expects "
                             f"({self.input_dim},)")
        if self._n != 1:
            self.reset_batch(1)
        a = self.act_batch(obs[None])[0]
        dt = float(self.info_batch["inference_time_s"][0])
        # "solve_time_s" too, so that tables of solve times include the learned controller
        self.info = {"inference_time_s": dt, "solve_time_s": dt}
        return a

    # ------------------------------------------------------------------ batched
    def reset_batch(self, n: int, seeds: Iterable[int] | None = None) -> None:
        """Start ``n`` episodes (rows).

        :param n: number of rows
        :param seeds: unused (the policy is deterministic)
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"reset_batch: n must be a positive integer, got {n!r}")
        self._n = int(n)
        self.interface = (None if self.spec is None
                          else PolicyInterface(self.spec, self.train_env_config, self._n))
        if self.interface is not None and self.target_config is not None:
            self.interface.set_context(self.target_config)  # e.g. where its encoders sit
        if self.interface is not None and self._reading is not None:
            self.interface.set_wind_readings(np.full(self._n, self._reading))
        self._state: Any = None
        self._starts = np.ones(self._n, bool)
        self.info_batch = {}

    def set_scenario(self, wind_speed: float, direction: Any = None) -> None:
        """The mean wind speed reading (m/s) of the following episodes (kept until the next call;
        the bench's episode loop passes the reset info's): a base scheduled on it designs for
        it. ``direction`` is not used.

        :raises ValueError: one line, for a speed that is not finite or outside 0..90 km/h
        """
        self._reading = float(check_readings(wind_speed, 1)[0])
        if self.interface is not None:
            self.interface.set_wind_readings(np.full(self._n, self._reading))

    def set_scenario_batch(self, wind_speeds: Any, directions: Any = None) -> None:
        """The rows' mean wind speed readings (m/s) of the episodes they start next (after
        :meth:`reset_batch` or :meth:`restart`); ``directions`` are not used.

        :raises ValueError: one line, unless one finite speed in 0..90 km/h per row
        """
        if self.interface is not None:
            self.interface.set_wind_readings(wind_speeds)

    def restart(self, mask: np.ndarray) -> None:
        """Rows ``mask`` (bool ``(n,)``) start new episodes at the next :meth:`act_batch`."""
        mask = np.asarray(mask, bool)
        if mask.shape != (self._n,):
            raise ValueError(f"restart: mask must have shape ({self._n},), got {mask.shape}")
        if self.interface is not None:
            self.interface.restart(mask)
        self._starts |= mask

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions ``(n, act_dim)`` float32 for observations ``(n, input_dim)``.

        :raises ValueError: wrong shape or non-finite observations (naming the rows)
        """
        t0 = time.perf_counter()
        obs = np.asarray(observations, dtype=np.float32)
        if obs.shape != (self._n, self.input_dim):
            raise ValueError(f"{self.name}: observation shape {obs.shape}, the policy expects "
                             f"({self._n}, {self.input_dim})")
        bad = ~np.isfinite(obs).all(axis=1)
        if bad.any():
            raise ValueError(f"{self.name}: non-finite observation in row(s) "
                             f"{np.flatnonzero(bad).tolist()}")
        feats = obs if self.interface is None else self.interface.observe(obs)
        x = feats if self.stats is None else self.stats.normalize(feats)
        if self.recurrent:
            u, self._state = self.policy.predict(x, state=self._state, episode_start=self._starts,
                                                 deterministic=True)
        elif self.gaussian_mlp:
            u = gaussian_mlp_actions(self.policy, x)
        else:
            u, _ = self.policy.predict(x, deterministic=True)
        self._starts = np.zeros(self._n, bool)
        u = np.asarray(u, np.float64).reshape(self._n, -1)
        a = u if self.interface is None else self.interface.action(u)
        if self.to_env != 1.0:
            a = np.clip(a * self.to_env, -1.0, 1.0)
        a = np.asarray(a, np.float32)
        dt = time.perf_counter() - t0
        per_row = np.full(self._n, dt / self._n)
        self.info_batch = {"inference_time_s": per_row, "solve_time_s": per_row}
        return a


#: the name of the PPO-only controller class of earlier versions
PPOController = PolicyController


def _label(files: PolicyFiles, algo: str) -> str:
    folder = files.folder
    name = folder.name
    if folder.parent.name == "eval":  # <run>/eval/best
        name = f"{folder.parent.parent.name}/{folder.name}"
    elif folder.parent.name == "checkpoints":
        name = f"{folder.parent.parent.name}/{folder.name}"
    return f"{ALGO_LABELS.get(algo, algo)} ({name})"


#: what a policy's ``config.yaml`` must state (the rest may take its defaults: a policy of the
#: PPO-only version states no ``algo``): the network is rebuilt from them
POLICY_KEYS = ("env_id", "net_arch")


def check_resolved(path: Path) -> None:
    """Refuse a policy's ``config.yaml`` that leaves out what rebuilds the network (an empty
    file would load as the defaults and fail at the first action).

    :raises PolicyFileError: naming the file and the missing fields
    """
    data, _ = read_config(path)
    missing = [k for k in POLICY_KEYS if k not in data]
    if missing:
        raise PolicyFileError(f"{path}: field '{missing[0]}': is missing (a policy's config.yaml "
                              f"is its run's resolved configuration, stating "
                              f"{', '.join(POLICY_KEYS)})")


#: policies a process keeps read (:func:`checked_policy`), the least recently used dropped first
POLICIES_KEPT = 16


def file_stamp(path: Path | None) -> tuple[str, str] | None:
    """``(resolved path, SHA-256 of the content)`` of a policy file, or None: what tells an
    edited file from the one read before (same size and time or not).

    :raises PolicyFileError: the file cannot be read
    """
    if path is None:
        return None
    try:
        return str(path.resolve()), hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise PolicyFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None


@functools.lru_cache(maxsize=POLICIES_KEPT)
def checked_policy(config: tuple[str, str], weights: tuple[str, str], stats: tuple[str, str] | None,
                   env_module: str | None = None
                   ) -> tuple[TrainConfig, dict[str, Any], dict, NormStats | None]:
    """The checked contents of a policy folder's files (:func:`file_stamp` of each): the
    configuration, the weights' fingerprint and state dict, and the statistics.  Read once per
    content and kept (:data:`POLICIES_KEPT`); shared, never changed: :func:`load_policy` copies
    the weights into a network of its own and the statistics.  ``checked_policy.cache_clear()``
    forgets them.

    :raises PolicyFileError: (a ValueError) one line naming the file: unreadable, weights and
        statistics of different runs
    """
    cfg_path, w_path = Path(config[0]), Path(weights[0])
    cfg = load_config(cfg_path, env_module)
    check_resolved(cfg_path)
    wfp, state = load_weights(w_path)
    if wfp["algo"] != cfg.algo:
        raise PolicyFileError(f"{w_path}: weights of algo {wfp['algo']!r}, "
                              f"{cfg_path} says {cfg.algo!r}")
    norm = None
    if cfg.normalize_obs:
        if stats is None:
            raise PolicyFileError(f"policy folder {w_path.parent}: normalization.npz is missing "
                                  f"({cfg_path} has normalize_obs: true)")
        s_path = Path(stats[0])
        sfp, norm = load_stats(s_path)
        check_fingerprints(w_path, wfp, s_path, sfp)
        if norm.obs_mean.size != int(wfp["obs_dim"]):
            raise PolicyFileError(f"{s_path}: statistics of {norm.obs_mean.size} "
                                  f"observations, the weights expect {wfp['obs_dim']}")
    return cfg, wfp, state, norm


def load_policy(path: str | Path | None = None, env: Any = None, name: str | None = None,
                trust_pickle: bool = False, torch_threads: int | None = 1,
                env_module: str | None = None) -> PolicyController:
    """Load a trained policy as a :class:`dss14_env.baselines.base.Controller`.

    The files of a policy folder are read every time; their checked contents are kept per
    content (:func:`checked_policy`), so a policy loaded again costs a fresh network only (an
    edited file is read anew).  Every controller gets a network and statistics of its own.

    :param path: a policy folder (run folder, ``eval/best``, ``checkpoints/<N>_steps``);
        default None: the policy shipped with the package (:data:`DEFAULT_POLICY`)
    :param env: the environment it will act on (see :class:`PolicyController`), default None
    :param name: label, default None: ``"<ALGO> (<folder>)"``
    :param trust_pickle: allow a foreign stable-baselines3 ``.zip`` / ``vecnormalize.pkl``
        (unpickled: can run code), default False
    :param torch_threads: see :class:`PolicyController`
    :param env_module: a module of yours that the policy's ``config.yaml`` may name to register
        its environment (the explicit opt-in: importing runs its code), default None: the file
        may name only this package's own modules (:func:`~dss14_env.agents.config.load_config`)
    :raises PolicyFileError: (a ValueError) one line naming the file: missing, unreadable,
        refused pickle, weights and statistics of different runs, weights that do not fit the
        configured architecture
    """
    files = find_policy_files(DEFAULT_POLICY if path is None else path)
    if files.foreign:
        cfg = None
        if files.config is not None:
            cfg = load_config(files.config, env_module)
            check_resolved(files.config)
        model, vn = load_sb3_model(files, algo_class(cfg.algo if cfg else "ppo"), trust_pickle)
        stats = NormStats.from_vec_normalize(vn) if vn is not None and vn.norm_obs else None
        algo = cfg.algo if cfg else "ppo"
        return PolicyController(model.policy, cfg, stats, name or _label(files, algo), env,
                                torch_threads)
    cfg, wfp, state, stats = checked_policy(file_stamp(files.config), file_stamp(files.weights),
                                            file_stamp(files.stats), env_module)
    low = wfp.get("action_low", [-1.0] * int(wfp["act_dim"]))
    high = wfp.get("action_high", [1.0] * int(wfp["act_dim"]))
    policy = build_policy(cfg, int(wfp["obs_dim"]), low, high)
    try:
        policy.load_state_dict(state, strict=True)
    except (RuntimeError, KeyError, TypeError) as exc:
        first = str(exc).strip().splitlines()[0][:160]
        raise PolicyFileError(f"{files.weights}: the weights do not fit the architecture of "
                              f"{files.config} ({first})") from None
    return PolicyController(policy, cfg, copy.deepcopy(stats), name or _label(files, cfg.algo), env,
                            torch_threads)


#: observation and action sizes of a DSS14 environment (what the runner gives a controller)
DSS14_OBS_DIM, DSS14_ACT_DIM = int(OBS_HIGH.size), 2


def dss14_policy_problem(path: str | Path, trust_pickle: bool = False) -> str | None:
    """Why the policy at ``path`` cannot act on a DSS14 environment (one line), or None.

    Loads it (:func:`load_policy`: layout, configuration, weights, statistics) and checks that
    it takes the DSS14 environment's 12 observations and gives its 2 actions -- so that a
    policy of another environment is refused before a benchmark or campaign starts, not
    scored as empty cells.
    """
    problem = policy_problem(path, trust_pickle)
    if problem is not None:
        return problem
    try:
        ctrl = load_policy(path, trust_pickle=trust_pickle)
    except (ValueError, OSError, RuntimeError) as exc:
        return " ".join(str(exc).split())
    act_dim = int(np.prod(ctrl.policy.action_space.shape))
    if ctrl.spec is not None:  # an interface turns the policy's output into the env's action
        act_dim = DSS14_ACT_DIM
    if ctrl.input_dim != DSS14_OBS_DIM or act_dim != DSS14_ACT_DIM:
        env = f" (trained on {ctrl.config.env_id})" if ctrl.config is not None else ""
        return (f"policy {path}{env} takes {ctrl.input_dim} observations and gives {act_dim} "
                f"actions; a DSS14 environment has {DSS14_OBS_DIM} and {DSS14_ACT_DIM}")
    return None


def _model_paths(path: str | Path) -> PolicyFiles:
    """The policy files at ``path``; raises ValueError (one line) when it cannot be loaded.

    Kept for callers of earlier versions; use :func:`find_policy_files` and
    :func:`policy_problem`.
    """
    problem = policy_problem(path)
    if problem is not None:
        raise PolicyFileError(problem)
    return find_policy_files(path)


def evaluate(path: str | Path, env_id: str | None = None, seeds: Iterable[int] = (0,),
             n_episodes: int = 1, env_kwargs: Mapping[str, Any] | None = None,
             trust_pickle: bool = False) -> dict[str, Any]:
    """Mean and spread of the episode return of the deterministic policy (a quick check; the
    project's runner and :mod:`dss14_env.agents.evaluation` do the real scoring).

    For every seed the first episode starts with ``reset(seed=seed)``; the next
    ``n_episodes - 1`` continue the environment's generator.  A policy with an interface
    (residual, model-informed, history) is stepped on the base environment underneath (same
    episodes, same rewards).

    :param path: a policy folder
    :param env_id: environment, default None: the run's
    :param seeds: episode seeds, default ``(0,)``
    :param n_episodes: episodes per seed, default 1
    :param env_kwargs: ``gymnasium.make`` arguments, default None: the run's (or none when
        ``env_id`` is given and differs from the run's)
    :param trust_pickle: see :func:`load_policy`
    :return: ``mean_return``, ``std_return``, ``min_return``, ``max_return``, ``returns``,
        ``lengths``, ``n_episodes`` (total), ``seeds``, ``env_id``, ``mean_inference_time_s``
    """
    ctrl = load_policy(path, trust_pickle=trust_pickle)
    cfg = ctrl.config
    if env_id is None:
        if cfg is None:
            raise ValueError(f"no config.yaml with the policy at {path}: pass env_id")
        env_id = cfg.env_id
    env_module = cfg.env_module if cfg is not None else None
    if env_kwargs is None:
        env_kwargs = cfg.env_kwargs if cfg is not None and cfg.env_id == env_id else {}
    seeds = [int(s) for s in seeds]
    if not seeds or n_episodes < 1:
        raise ValueError("evaluate: need at least one seed and n_episodes >= 1")
    if cfg is not None and env_id == cfg.env_id and ctrl.spec is not None:
        plan = resolve_env(cfg.replace(env_kwargs=dict(env_kwargs)))
        env_id, env_kwargs = plan.base_id, dict(plan.base_kwargs)
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


__all__ = ["ALGO_LABELS", "DEFAULT_POLICY", "DSS14_ACT_DIM", "DSS14_OBS_DIM", "POLICIES_DIR",
           "POLICIES_KEPT", "PPOController", "PolicyController",
           "PolicyFiles", "checked_policy", "file_stamp", "gaussian_mlp_actions", "is_gaussian_mlp",
           "shipped_policies", "shipped_policy",
           "dss14_policy_problem", "evaluate", "find_policy_files", "load_policy",
           "policy_problem"]
