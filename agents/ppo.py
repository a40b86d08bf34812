"""PPO training (stable-baselines3) for any Gymnasium environment id, ``DSS14-v0`` by default.

The configuration is a typed, validated :class:`PPOConfig` read from ``configs/ppo.yaml``; a bad
key or value raises :class:`ValueError` naming the key and the file.  :func:`train` writes
everything of one run into one folder (default ``runs/ppo-<timestamp>/``)::

    config.yaml                  resolved configuration (every key; loads back with load_config)
    model.zip, vecnormalize.pkl  final policy and its frozen observation-normalisation stats
    checkpoints/                 ppo_<N>_steps.zip + ppo_vecnormalize_<N>_steps.pkl
    eval/                        evaluations.npz, best/model.zip + best/vecnormalize.pkl
    tb/                          TensorBoard event files (if tensorboard is installed)
    monitor/                     per-env training episode CSVs (SB3 Monitor)
    train_summary.json           timesteps, wall time, throughput, versions

Load a trained policy with :func:`dss14_env.agents.policy.load_policy` (a
:class:`dss14_env.baselines.base.Controller`), score it with :func:`dss14_env.agents.policy.evaluate`.

>>> cfg = PPOConfig.from_dict({"env_id": "Pendulum-v1", "n_envs": 2, "n_steps": 64,
...                            "batch_size": 64})
>>> cfg.n_envs, cfg.vec_env
(2, 'dummy')
>>> PPOConfig.from_dict({"env_id": "Pendulum-v1", "n_env": 2})
Traceback (most recent call last):
...
ValueError: <dict>: unknown key 'n_env' (did you mean 'n_envs'?)
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import importlib
import importlib.util
import json
import math
import re
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

#: modules imported (when present) before ``gymnasium.make`` if ``env_id`` is not registered and
#: the config names no ``env_module``: where ``DSS14-v0`` registers itself.
DEFAULT_ENV_MODULES = ("dss14_env",)

_ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")
_VEC_ENVS = ("dummy", "subproc")
_CKPT_RE = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps\.zip$")


# --------------------------------------------------------------------------------------------
# configuration
# --------------------------------------------------------------------------------------------
def _default_eval_seeds() -> list[int]:
    return [1000, 1001, 1002, 1003, 1004]


def _default_net_arch() -> list[int]:
    return [64, 64]


@dataclass(frozen=True)
class PPOConfig:
    """Everything one PPO run needs; defaults as in the shipped ``configs/ppo.yaml``.

    Frequencies (``eval_freq``, ``checkpoint_freq``) count environment steps summed over all
    ``n_envs`` copies, like ``total_timesteps``; 0 disables.

    :param env_id: Gymnasium id (``"module:Id"`` also works), default ``"DSS14-v0"``
    :param env_kwargs: keyword arguments of ``gymnasium.make``, default ``{}``
    :param env_module: module imported before ``gymnasium.make`` to register ``env_id``; default
        None: ``dss14_env`` / ``dss14_env.envs.env`` are tried when the id is not registered
    :param n_envs: parallel environment copies, default 8
    :param vec_env: ``"dummy"`` (one process) or ``"subproc"`` (one process per copy), default
        ``"dummy"``
    :param total_timesteps: training budget in environment steps; on resume the overall target,
        checkpoint steps included; default 2_000_000
    :param seed: seed of the policy initialisation, sampling and training environments; copy
        ``i`` starts from ``seed + i``; default 0
    :param normalize_obs: running mean/std observation normalisation (VecNormalize), default True
    :param normalize_reward: running return-scale reward normalisation, default True
    :param learning_rate: Adam step size (constant), default 3e-4
    :param n_steps: steps per environment copy per rollout, default 256
    :param batch_size: minibatch size; must divide ``n_steps * n_envs``; default 256
    :param n_epochs: optimisation passes per rollout, default 10
    :param gamma: discount factor, default 0.99
    :param gae_lambda: GAE lambda, default 0.95
    :param clip_range: PPO ratio clip, default 0.2
    :param ent_coef: entropy bonus, default 0.0
    :param vf_coef: value-loss weight, default 0.5
    :param max_grad_norm: gradient-norm clip, default 0.5
    :param target_kl: early-stop an update when the KL exceeds it, default None (off)
    :param net_arch: hidden layers, a list (same sizes for separate policy and value nets) or
        ``{"pi": [...], "vf": [...]}``, default ``[64, 64]``
    :param activation_fn: ``"tanh"``, ``"relu"``, ``"elu"`` or ``"leaky_relu"``, default
        ``"tanh"``
    :param log_std_init: initial log standard deviation of the Gaussian policy, default -0.5
    :param eval_freq: evaluate the deterministic policy every this many steps, default 50_000
    :param n_eval_episodes: evaluation episodes per evaluation seed, default 1
    :param eval_seeds: one evaluation environment per seed, reset with it at every evaluation,
        default ``[1000, 1001, 1002, 1003, 1004]``
    :param eval_env_kwargs: keys laid over ``env_kwargs`` for the evaluation environments (the
        validation task that picks ``eval/best``), default ``{}``: the training environment
    :param checkpoint_freq: save model + VecNormalize stats every this many steps, default
        200_000
    :param progress_bar: tqdm/rich progress bar (skipped with a note if not installed), default
        True
    :param verbose: 0 silent, 1 SB3 training tables and notes, 2 debug; default 1
    :param source: file the values came from (error messages only), default ``"<PPOConfig>"``
    """

    env_id: str = "DSS14-v0"
    env_kwargs: dict = field(default_factory=dict)
    env_module: str | None = None
    n_envs: int = 8
    vec_env: str = "dummy"
    total_timesteps: int = 2_000_000
    seed: int = 0
    normalize_obs: bool = True
    normalize_reward: bool = True
    learning_rate: float = 3e-4
    n_steps: int = 256
    batch_size: int = 256
    n_epochs: int = 10
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_kl: float | None = None
    net_arch: Any = field(default_factory=_default_net_arch)
    activation_fn: str = "tanh"
    log_std_init: float = -0.5
    eval_freq: int = 50_000
    n_eval_episodes: int = 1
    eval_seeds: list = field(default_factory=_default_eval_seeds)
    eval_env_kwargs: dict = field(default_factory=dict)
    checkpoint_freq: int = 200_000
    progress_bar: bool = True
    verbose: int = 1
    source: str = field(default="<PPOConfig>", repr=False, compare=False)

    def __post_init__(self) -> None:
        values = {f.name: getattr(self, f.name) for f in _config_fields()}
        for name, value in _check_values(values, self.source).items():
            object.__setattr__(self, name, value)

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> PPOConfig:
        """Build a validated config from a mapping; missing keys take their defaults.

        :param data: key -> value, as in ``configs/ppo.yaml``
        :param source: name used in error messages, default ``"<dict>"``
        :return: the config
        :raises ValueError: unknown key or bad value, naming the key and ``source``
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a mapping of PPO settings, got "
                             f"{type(data).__name__}")
        names = [f.name for f in _config_fields()]
        for key in data:
            if key not in names:
                near = difflib.get_close_matches(str(key), names, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise ValueError(f"{source}: unknown key {key!r}{hint}")
        return cls(**dict(data), source=source)

    def replace(self, **changes: Any) -> PPOConfig:
        """Copy with some values changed (validated again), e.g. ``cfg.replace(seed=3)``."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain-YAML mapping of every key (loads back with :meth:`from_dict`)."""
        out = {}
        for f in _config_fields():
            v = getattr(self, f.name)
            # deep copy into plain YAML types (tuples -> lists, numpy scalars -> Python)
            out[f.name] = json.loads(json.dumps(v, default=lambda o: o.item()
                                                if hasattr(o, "item") else str(o)))
        return out


def _config_fields() -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(PPOConfig) if f.name != "source"]


def _bad(source: str, key: str, msg: str, value: Any) -> ValueError:
    return ValueError(f"{source}: key {key!r}: {msg}, got {value!r}")


def _as_int(v: Any, key: str, source: str, lo: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        if isinstance(v, float) and v.is_integer():  # 1e6 in YAML
            v = int(v)
        else:
            bound = f" >= {lo}" if lo is not None else ""
            raise _bad(source, key, f"must be an integer{bound}", v)
    v = int(v)
    if lo is not None and v < lo:
        raise _bad(source, key, f"must be an integer >= {lo}", v)
    return v


def _as_float(v: Any, key: str, source: str, lo: float | None = None, hi: float | None = None,
              lo_open: bool = False, hi_open: bool = False) -> float:
    if isinstance(v, str):  # PyYAML reads "3e-4" (no dot) as a string
        try:
            v = float(v)
        except ValueError:
            pass
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise _bad(source, key, "must be a number", v)
    v = float(v)
    lo_s = "" if lo is None else (f"> {lo}" if lo_open else f">= {lo}")
    hi_s = "" if hi is None else (f"< {hi}" if hi_open else f"<= {hi}")
    rng = " and ".join(s for s in (lo_s, hi_s) if s)
    if (not math.isfinite(v) or (lo is not None and (v <= lo if lo_open else v < lo))
            or (hi is not None and (v >= hi if hi_open else v > hi))):
        raise _bad(source, key, f"must be a finite number{' ' + rng if rng else ''}", v)
    return v


def _as_bool(v: Any, key: str, source: str) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise _bad(source, key, "must be true or false", v)
    return bool(v)


def _as_choice(v: Any, key: str, source: str, choices: tuple[str, ...]) -> str:
    if not isinstance(v, str) or v not in choices:
        raise _bad(source, key, f"must be one of {', '.join(choices)}", v)
    return v


def _as_layers(v: Any, key: str, source: str) -> list[int]:
    if not isinstance(v, (list, tuple)) or not all(
            isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in v):
        raise _bad(source, key, "must be a list of layer sizes (integers >= 1)", v)
    return [int(n) for n in v]


def _check_values(c: dict[str, Any], source: str) -> dict[str, Any]:
    """Validate and normalise every value; cross-key checks last."""
    out = dict(c)
    if not isinstance(c["env_id"], str) or not c["env_id"].strip():
        raise _bad(source, "env_id", "must be a non-empty Gymnasium id", c["env_id"])
    kw = c["env_kwargs"]
    if not isinstance(kw, Mapping) or not all(isinstance(k, str) for k in kw):
        raise _bad(source, "env_kwargs", "must be a mapping of keyword arguments", c["env_kwargs"])
    out["env_kwargs"] = dict(c["env_kwargs"])
    kw = c["eval_env_kwargs"]
    if not isinstance(kw, Mapping) or not all(isinstance(k, str) for k in kw):
        raise _bad(source, "eval_env_kwargs", "must be a mapping of keyword arguments", kw)
    out["eval_env_kwargs"] = dict(kw)
    mod = c["env_module"]
    if mod is not None and (not isinstance(mod, str) or not mod):
        raise _bad(source, "env_module", "must be a module name or null", c["env_module"])
    for k, lo in (("n_envs", 1), ("total_timesteps", 1), ("seed", 0), ("n_steps", 1),
                  ("batch_size", 2), ("n_epochs", 1), ("eval_freq", 0), ("n_eval_episodes", 1),
                  ("checkpoint_freq", 0)):
        out[k] = _as_int(c[k], k, source, lo)
    out["vec_env"] = _as_choice(c["vec_env"], "vec_env", source, _VEC_ENVS)
    out["activation_fn"] = _as_choice(c["activation_fn"], "activation_fn", source, _ACTIVATIONS)
    for k in ("normalize_obs", "normalize_reward", "progress_bar"):
        out[k] = _as_bool(c[k], k, source)
    out["verbose"] = _as_int(c["verbose"], "verbose", source, 0)
    if out["verbose"] > 2:
        raise _bad(source, "verbose", "must be 0, 1 or 2", c["verbose"])
    out["learning_rate"] = _as_float(c["learning_rate"], "learning_rate", source, 0.0, lo_open=True)
    out["gamma"] = _as_float(c["gamma"], "gamma", source, 0.0, 1.0, lo_open=True)
    out["gae_lambda"] = _as_float(c["gae_lambda"], "gae_lambda", source, 0.0, 1.0)
    out["clip_range"] = _as_float(c["clip_range"], "clip_range", source, 0.0, lo_open=True)
    out["ent_coef"] = _as_float(c["ent_coef"], "ent_coef", source, 0.0)
    out["vf_coef"] = _as_float(c["vf_coef"], "vf_coef", source, 0.0)
    out["max_grad_norm"] = _as_float(c["max_grad_norm"], "max_grad_norm", source, 0.0, lo_open=True)
    out["log_std_init"] = _as_float(c["log_std_init"], "log_std_init", source, -20.0, 5.0)
    if c["target_kl"] is not None:
        out["target_kl"] = _as_float(c["target_kl"], "target_kl", source, 0.0, lo_open=True)
    na = c["net_arch"]
    if isinstance(na, Mapping):
        if set(na) != {"pi", "vf"}:
            raise _bad(source, "net_arch", "a mapping must have exactly the keys pi and vf", na)
        out["net_arch"] = {k: _as_layers(na[k], f"net_arch.{k}", source) for k in ("pi", "vf")}
    else:
        out["net_arch"] = _as_layers(na, "net_arch", source)
    seeds = c["eval_seeds"]
    if not isinstance(seeds, (list, tuple)) or not seeds:
        raise _bad(source, "eval_seeds", "must be a non-empty list of integers >= 0", seeds)
    out["eval_seeds"] = [_as_int(s, "eval_seeds", source, 0) for s in seeds]
    rollout = out["n_steps"] * out["n_envs"]
    if out["batch_size"] > rollout or rollout % out["batch_size"]:
        raise _bad(source, "batch_size", f"must divide n_steps * n_envs = {rollout}",
                   out["batch_size"])
    return out


def default_config_path(name: str = "ppo.yaml") -> Path:
    """Path of a PPO configuration shipped in the ``configs`` package.

    :param name: file name, default ``"ppo.yaml"`` (``"ppo_smoke.yaml"``: Pendulum-v1 smoke run)
    """
    return Path(str(resources.files("dss14_env.configs").joinpath(name)))


def load_config(path: str | Path | None = None) -> PPOConfig:
    """Read and validate a PPO YAML file.

    :param path: the file, default None: the shipped ``configs/ppo.yaml``
    :return: the config
    :raises ValueError: missing/unreadable file, unknown key or bad value (names key and file)
    """
    p = Path(path) if path is not None else default_config_path()
    if not p.is_file():
        raise ValueError(f"PPO config file not found: {p}")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{p}: not valid YAML: {exc}".replace("\n", " ")) from exc
    return PPOConfig.from_dict(data if data is not None else {}, source=str(p))


def as_config(config: PPOConfig | Mapping[str, Any] | str | Path) -> PPOConfig:
    """A :class:`PPOConfig` from a config, a mapping or a YAML path."""
    if isinstance(config, PPOConfig):
        return config
    if isinstance(config, Mapping):
        return PPOConfig.from_dict(config)
    if isinstance(config, (str, Path)):
        return load_config(config)
    raise ValueError(f"config must be a PPOConfig, a mapping or a YAML path, got "
                     f"{type(config).__name__}")


# --------------------------------------------------------------------------------------------
# environments
# --------------------------------------------------------------------------------------------
def import_env_module(env_id: str, env_module: str | None = None) -> None:
    """Import the module that registers ``env_id`` (a no-op when it is registered already).

    :param env_id: Gymnasium id
    :param env_module: module to import, default None: :data:`DEFAULT_ENV_MODULES` are tried
        when ``env_id`` is not registered yet
    """
    if env_module:
        importlib.import_module(env_module)
        return
    if ":" in env_id or env_id in gym.registry:
        return
    for mod in DEFAULT_ENV_MODULES:
        if importlib.util.find_spec(mod.split(".")[0]) is None:
            continue
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:  # a genuine missing dependency inside the module
                raise
        if env_id in gym.registry:
            return


def make_env(env_id: str, env_kwargs: Mapping[str, Any] | None = None,
             env_module: str | None = None) -> Any:
    """``gymnasium.make(env_id, **env_kwargs)`` after importing the registering module.

    Module-level (picklable) so that :class:`SubprocVecEnv` workers can call it.

    :param env_id: Gymnasium id
    :param env_kwargs: keyword arguments of ``gymnasium.make``, default None
    :param env_module: see :func:`import_env_module`, default None
    """
    import_env_module(env_id, env_module)
    return gym.make(env_id, **dict(env_kwargs or {}))


def _check_env(cfg: PPOConfig) -> tuple[Any, Any]:
    """Make one environment in this process: a clear error early, and its spaces."""
    try:
        env = make_env(cfg.env_id, cfg.env_kwargs, cfg.env_module)
    except Exception as exc:  # gymnasium.error.*, TypeError from bad env_kwargs, ImportError
        raise ValueError(f"{cfg.source}: key 'env_id': cannot make {cfg.env_id!r} with env_kwargs "
                         f"{cfg.env_kwargs}: {type(exc).__name__}: {exc}") from exc
    try:
        spaces_ = env.observation_space, env.action_space
    finally:
        env.close()
    if cfg.eval_env_kwargs:
        kw = {**cfg.env_kwargs, **cfg.eval_env_kwargs}
        try:
            make_env(cfg.env_id, kw, cfg.env_module).close()
        except Exception as exc:  # noqa: BLE001 - same as above, for the evaluation environment
            raise ValueError(f"{cfg.source}: key 'eval_env_kwargs': cannot make {cfg.env_id!r} "
                             f"with {kw}: {type(exc).__name__}: {exc}") from exc
    return spaces_


class EvalSeedWrapper(gym.Wrapper):
    """Resets with a fixed seed the first time after :meth:`arm` (and after construction).

    The evaluation environment of one eval seed: every evaluation starts from the same episode,
    later episodes of the same evaluation continue the environment's generator, exactly as
    :func:`dss14_env.agents.policy.evaluate` does.

    :param env: the environment
    :param seed: its evaluation seed
    """

    def __init__(self, env: gym.Env, seed: int) -> None:
        super().__init__(env)
        self.eval_seed = int(seed)
        self._armed = True

    def arm(self) -> None:
        """Make the next seedless reset use :attr:`eval_seed`."""
        self._armed = True

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> Any:
        if self._armed and seed is None:
            seed = self.eval_seed
        self._armed = False
        return self.env.reset(seed=seed, options=options)


def _make_eval_env(cfg: PPOConfig, seed: int) -> Any:
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(make_env(cfg.env_id, {**cfg.env_kwargs, **cfg.eval_env_kwargs}, cfg.env_module))
    return EvalSeedWrapper(env, seed)


def _make_train_vec_env(cfg: PPOConfig, monitor_dir: Path | None) -> Any:
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    factory = functools.partial(make_env, cfg.env_id, cfg.env_kwargs, cfg.env_module)
    return make_vec_env(factory, n_envs=cfg.n_envs, seed=cfg.seed,
                        monitor_dir=None if monitor_dir is None else str(monitor_dir),
                        vec_env_cls=SubprocVecEnv if cfg.vec_env == "subproc" else DummyVecEnv)


# --------------------------------------------------------------------------------------------
# paths
# --------------------------------------------------------------------------------------------
def vecnormalize_path_for(model_path: str | Path) -> Path:
    """The VecNormalize stats saved with a model zip.

    ``<dir>/model.zip`` -> ``<dir>/vecnormalize.pkl``; a checkpoint ``<dir>/ppo_<N>_steps.zip``
    -> ``<dir>/ppo_vecnormalize_<N>_steps.pkl``.
    """
    p = Path(model_path)
    m = _CKPT_RE.match(p.name)
    if m:
        return p.with_name(f"{m['prefix']}_vecnormalize_{m['steps']}_steps.pkl")
    return p.with_name("vecnormalize.pkl")


def _new_run_dir(root: Path = Path("runs")) -> Path:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    run = root / f"ppo-{stamp}"
    i = 1
    while run.exists():
        i += 1
        run = root / f"ppo-{stamp}-{i}"
    return run


def _resume_run_dir(ckpt: Path) -> Path:
    """The run folder a checkpoint belongs to (``<run>/checkpoints/x.zip`` -> ``<run>``)."""
    return ckpt.parent.parent if ckpt.parent.name == "checkpoints" else ckpt.parent


def _policy_kwargs(cfg: PPOConfig) -> dict[str, Any]:
    import torch.nn as nn

    act = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
    net_arch = dict(cfg.net_arch) if isinstance(cfg.net_arch, dict) else list(cfg.net_arch)
    return {"net_arch": net_arch, "activation_fn": act[cfg.activation_fn],
            "log_std_init": cfg.log_std_init}


def _ppo_kwargs(cfg: PPOConfig) -> dict[str, Any]:
    return dict(learning_rate=cfg.learning_rate, n_steps=cfg.n_steps, batch_size=cfg.batch_size,
                n_epochs=cfg.n_epochs, gamma=cfg.gamma, gae_lambda=cfg.gae_lambda,
                clip_range=cfg.clip_range, ent_coef=cfg.ent_coef, vf_coef=cfg.vf_coef,
                max_grad_norm=cfg.max_grad_norm, target_kl=cfg.target_kl)


def _installed(*modules: str) -> bool:
    return all(importlib.util.find_spec(m) is not None for m in modules)


# --------------------------------------------------------------------------------------------
# callbacks
# --------------------------------------------------------------------------------------------
def _callbacks(cfg: PPOConfig, run: Path, resume_steps: int) -> tuple[list[Any], Any]:
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    class SaveBest(BaseCallback):
        """On a new best evaluation: the policy and the stats it was evaluated with."""

        def _on_step(self) -> bool:
            best = run / "eval" / "best"
            best.mkdir(parents=True, exist_ok=True)
            self.model.save(best / "model.zip")
            vn = self.model.get_vec_normalize_env()
            if vn is not None:
                vn.save(str(best / "vecnormalize.pkl"))
            return True

    class SeededEval(EvalCallback):
        """EvalCallback whose environments restart from their eval seeds at every evaluation."""

        def _on_step(self) -> bool:
            if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
                self.eval_env.env_method("arm")
            return super()._on_step()

    callbacks: list[Any] = []
    eval_env = None
    per_call = lambda steps: max(steps // cfg.n_envs, 1)  # noqa: E731  (callbacks count vec steps)
    if cfg.checkpoint_freq > 0:
        callbacks.append(CheckpointCallback(per_call(cfg.checkpoint_freq), str(run / "checkpoints"),
                                            name_prefix="ppo", save_vecnormalize=True,
                                            verbose=min(cfg.verbose, 2)))
    if cfg.eval_freq > 0:
        eval_env = DummyVecEnv([functools.partial(_make_eval_env, cfg, s) for s in cfg.eval_seeds])
        eval_env = VecNormalize(eval_env, training=False, norm_obs=cfg.normalize_obs,
                                norm_reward=False)
        cb = SeededEval(eval_env, callback_on_new_best=SaveBest(),
                        n_eval_episodes=cfg.n_eval_episodes * len(cfg.eval_seeds),
                        eval_freq=per_call(cfg.eval_freq), log_path=str(run / "eval"),
                        best_model_save_path=None, deterministic=True, verbose=min(cfg.verbose, 1))
        old = run / "eval" / "evaluations.npz"
        if resume_steps > 0 and old.is_file():  # continue the evaluation history of the run
            with np.load(old) as d:
                keep = d["timesteps"] <= resume_steps
                cb.evaluations_timesteps = [int(t) for t in d["timesteps"][keep]]
                cb.evaluations_results = [list(r) for r in d["results"][keep]]
                cb.evaluations_length = [list(r) for r in d["ep_lengths"][keep]]
            if cb.evaluations_results:
                cb.best_mean_reward = float(max(np.mean(r) for r in cb.evaluations_results))
        callbacks.append(cb)
    return callbacks, eval_env


# --------------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------------
def train(config: PPOConfig | Mapping[str, Any] | str | Path, run_dir: str | Path | None = None,
          resume: str | Path | None = None) -> Path:
    """Train PPO (stable-baselines3, CPU, one torch thread) and write the run folder.

    :param config: a :class:`PPOConfig`, a mapping of its keys, or a YAML path
    :param run_dir: output folder, default None: ``runs/ppo-<timestamp>/`` for a new run, the
        checkpoint's run folder on resume; a new run refuses a folder that holds a model.zip
    :param resume: checkpoint (``.../checkpoints/ppo_<N>_steps.zip``) or ``model.zip`` to
        continue from, with its VecNormalize stats; the timestep counter continues
        (``reset_num_timesteps=False``) up to ``config.total_timesteps``; default None
    :return: the run folder
    :raises ValueError: bad config, unmakeable environment, missing checkpoint/stats, budget
        already reached, or a policy architecture that differs from the checkpoint's
    """
    import stable_baselines3
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    cfg = as_config(config)
    torch.set_num_threads(1)
    ckpt = vn_path = None
    if resume is not None:
        ckpt = Path(resume)
        if not ckpt.is_file():
            raise ValueError(f"resume checkpoint not found: {ckpt}")
        vn_path = vecnormalize_path_for(ckpt)
        if not vn_path.is_file():
            raise ValueError(f"VecNormalize stats of checkpoint {ckpt} not found: {vn_path}")
    if run_dir is not None:
        run = Path(run_dir)
    elif ckpt is not None:
        run = _resume_run_dir(ckpt)
    else:
        run = _new_run_dir()
    if ckpt is None and (run / "model.zip").exists():
        raise ValueError(f"run folder {run} already holds a model.zip; choose another folder "
                         f"(--out) or resume from a checkpoint (--resume)")
    obs_space, act_space = _check_env(cfg)
    say = print if cfg.verbose else (lambda *a, **k: None)

    run.mkdir(parents=True, exist_ok=True)
    (run / "config.yaml").write_text(
        f"# resolved PPO configuration of this run (from {cfg.source})\n"
        + yaml.safe_dump(cfg.to_dict(), sort_keys=False))
    tb = None
    if _installed("tensorboard"):
        tb = str(run / "tb")
    else:
        print("note: tensorboard is not installed; training curves go to monitor/ and "
              "eval/evaluations.npz only (pip install tensorboard)")
    progress = cfg.progress_bar
    if progress and not _installed("tqdm", "rich"):
        print("note: tqdm and rich are not installed; no progress bar (pip install tqdm rich)")
        progress = False

    start = 0
    if ckpt is not None:
        from stable_baselines3.common.save_util import load_from_zip_file

        data, _, _ = load_from_zip_file(ckpt, device="cpu", load_data=True)
        start = int((data or {}).get("num_timesteps", 0))
        if start >= cfg.total_timesteps:
            raise ValueError(f"checkpoint {ckpt} is at {start} steps, total_timesteps is "
                             f"{cfg.total_timesteps}: raise total_timesteps (--timesteps)")
    monitor = run / "monitor" / (f"resume_{start}_steps" if ckpt is not None else "")
    venv = _make_train_vec_env(cfg, monitor)
    eval_env = None
    try:
        if ckpt is not None:
            venv = VecNormalize.load(str(vn_path), venv)
            venv.training, venv.norm_reward = True, cfg.normalize_reward
            try:
                model = PPO.load(ckpt, env=venv, device="cpu", tensorboard_log=tb,
                                 verbose=cfg.verbose, policy_kwargs=_policy_kwargs(cfg),
                                 **_ppo_kwargs(cfg))
            except ValueError as exc:
                raise ValueError(f"{cfg.source}: keys 'net_arch'/'activation_fn'/'log_std_init' "
                                 f"do not match checkpoint {ckpt}: {exc}") from exc
            say(f"resuming {ckpt} at {start} steps (VecNormalize stats: {vn_path.name})")
        else:
            venv = VecNormalize(venv, norm_obs=cfg.normalize_obs, norm_reward=cfg.normalize_reward,
                                gamma=cfg.gamma)
            model = PPO("MlpPolicy", venv, policy_kwargs=_policy_kwargs(cfg), seed=cfg.seed,
                        device="cpu", tensorboard_log=tb, verbose=cfg.verbose, **_ppo_kwargs(cfg))
        callbacks, eval_env = _callbacks(cfg, run, start)
        say(f"PPO on {cfg.env_id}: {cfg.n_envs} x {cfg.vec_env} envs, obs {obs_space.shape}, "
            f"action {act_space.shape}, {cfg.total_timesteps - start} steps -> {run}")
        t0 = time.perf_counter()
        model.learn(total_timesteps=cfg.total_timesteps - start, callback=callbacks,
                    tb_log_name="PPO", reset_num_timesteps=ckpt is None, progress_bar=progress)
        wall = time.perf_counter() - t0
        model.save(run / "model.zip")
        venv.save(str(run / "vecnormalize.pkl"))
    finally:
        venv.close()
        if eval_env is not None:
            eval_env.close()
    summary = {
        "env_id": cfg.env_id, "num_timesteps": int(model.num_timesteps), "start_timesteps": start,
        "wall_s": round(wall, 3), "steps_per_s": round((model.num_timesteps - start) / wall, 1),
        "resumed_from": None if ckpt is None else str(ckpt), "seed": cfg.seed,
        "n_envs": cfg.n_envs, "vec_env": cfg.vec_env,
        "versions": {"stable_baselines3": stable_baselines3.__version__,
                     "torch": torch.__version__, "numpy": np.__version__},
    }
    (run / "train_summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    say(f"{model.num_timesteps} steps in {wall:.1f} s ({summary['steps_per_s']} steps/s); "
        f"run folder {run}")
    return run


__all__ = ["DEFAULT_ENV_MODULES", "EvalSeedWrapper", "PPOConfig", "as_config",
           "default_config_path", "import_env_module", "load_config", "make_env", "train",
           "vecnormalize_path_for"]
