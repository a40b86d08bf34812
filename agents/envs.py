"""The environments the agents train on: registered wrapper ids, and the training VecEnv.

Registered here (and by ``import dss14_env``), each a DSS14 environment seen through a
:class:`dss14_env.agents.interface.PolicyInterface`:

=========================  ==========================================================================
``DSS14-Plain-v0``         the policy sets the rate command; observation without the absolute angles
                           (entries 4, 5, 8, 9) + an 8-step history of errors and applied rates
``DSS14-Residual-v0``      residual on the report's PI: ``a = a_PI + 0.05 u``; observation + PI
                           integral term (+ history)
``DSS14-ResidualLQG-v0``   residual on the LQG: ``a = a_LQG + 0.02 u``; observation + the LQG's
                           command, disturbance and Kalman state estimate (model-informed)
``DSS14-KalmanObs-v0``     the policy sets the rate command; observation + the LQG's command,
                           disturbance and Kalman state estimate (model-informed)
=========================  ==========================================================================

Their keyword arguments: ``base_id`` (the DSS14 environment underneath, default
``DSS14-Hold-v0``), the interface keys (``gains``, ``residual_scale``, ``history``,
``history_entries``, ``obs_entries``, ``estimate``, ``lqg_features``) and any keyword of
``gymnasium.make(base_id, ...)`` (environment keys
such as ``action_scale_deg_s`` or ``wind_speed_kmh``, and ``max_episode_steps``).

:func:`resolve_env` turns a training configuration into the base environment and the
interface; :func:`make_train_vec_env` builds the training VecEnv -- the batched one
(:mod:`dss14_env.agents.vec_env` + :class:`~dss14_env.agents.vec_env.InterfaceVecEnv`) for
DSS14 environments, SB3's ``DummyVecEnv``/``SubprocVecEnv`` otherwise.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym

from dss14_env.agents.config import TrainConfig
from dss14_env.agents.interface import (
    NO_ABSOLUTE_ANGLES,
    READING_CONTEXT,
    SCHEDULED_BASE,
    InterfaceSpec,
    InterfaceWrapper,
    spec_from_kwargs,
)

if TYPE_CHECKING:  # annotations only: the SB3 VecEnvs (torch) are imported where they are built
    from dss14_env.agents.vec_env import MixtureVecEnv

#: modules imported (when present) before ``gymnasium.make`` if ``env_id`` is not registered and
#: the config names no ``env_module``
DEFAULT_ENV_MODULES = ("dss14_env", "dss14_env.agents")
DEFAULT_BASE_ID = "DSS14-Hold-v0"

#: the wrapper ids and the defaults of their interfaces
WRAPPER_IDS: dict[str, InterfaceSpec] = {
    "DSS14-Plain-v0": InterfaceSpec(obs_entries=NO_ABSOLUTE_ANGLES, history=8),
    "DSS14-Residual-v0": InterfaceSpec(base="pi", action="residual", residual_scale=0.05),
    "DSS14-ResidualLQG-v0": InterfaceSpec(base="lqg", action="residual", residual_scale=0.02),
    "DSS14-KalmanObs-v0": InterfaceSpec(base="lqg", action="absolute"),
}


def make_wrapped_env(env_id: str, base_id: str = DEFAULT_BASE_ID, **kwargs: Any) -> InterfaceWrapper:
    """The entry point of a wrapper id: ``InterfaceWrapper(gymnasium.make(base_id, ...))``.

    :param env_id: the wrapper id (its interface defaults)
    :param base_id: the DSS14 environment underneath
    :param kwargs: interface keys and keyword arguments of ``gymnasium.make(base_id, ...)``
    """
    import dss14_env  # noqa: F401  (registers the base environments)

    spec, env_kwargs = spec_from_kwargs(kwargs, WRAPPER_IDS[env_id])
    return InterfaceWrapper(gym.make(base_id, disable_env_checker=True, **env_kwargs), spec)


def make_plain_env(base_id: str = DEFAULT_BASE_ID, **kwargs: Any) -> InterfaceWrapper:
    """The entry point of ``DSS14-Plain-v0`` (see :func:`make_wrapped_env`)."""
    return make_wrapped_env("DSS14-Plain-v0", base_id, **kwargs)


def make_residual_lqg_env(base_id: str = DEFAULT_BASE_ID, **kwargs: Any) -> InterfaceWrapper:
    """The entry point of ``DSS14-ResidualLQG-v0`` (see :func:`make_wrapped_env`)."""
    return make_wrapped_env("DSS14-ResidualLQG-v0", base_id, **kwargs)


def make_kalman_obs_env(base_id: str = DEFAULT_BASE_ID, **kwargs: Any) -> InterfaceWrapper:
    """The entry point of ``DSS14-KalmanObs-v0`` (see :func:`make_wrapped_env`)."""
    return make_wrapped_env("DSS14-KalmanObs-v0", base_id, **kwargs)


# ---------------------------------------------------------------------------- resolution
@dataclass(frozen=True)
class EnvPlan:
    """What a configuration trains on.

    :param base_id: the environment the steps run in (a DSS14 id, or any Gymnasium id)
    :param base_kwargs: its ``gymnasium.make`` keyword arguments (``max_episode_steps`` too)
    :param interface: the policy interface on top (None: the environment's own spaces)
    :param dss14: the base environment is a DSS14 environment
    """

    base_id: str
    base_kwargs: Mapping[str, Any]
    interface: InterfaceSpec | None
    dss14: bool


def import_env_module(env_id: str, env_module: str | None = None) -> None:
    """Import the module that registers ``env_id`` (a no-op when it is registered already)."""
    if env_module:
        importlib.import_module(env_module)
        return
    if ":" in env_id or env_id in gym.registry:
        return
    for mod in DEFAULT_ENV_MODULES:
        if importlib.util.find_spec(mod.split(".")[0]) is None:
            continue
        importlib.import_module(mod)
        if env_id in gym.registry:
            return


def check_registered(env_id: Any, source: str, field: str) -> None:
    """Refuse an environment id that is not registered with gymnasium (after the registering
    modules were imported): ``gymnasium.make`` then only builds registered environments and
    imports nothing a configuration names.

    :raises ValueError: ``<source>: field '<field>': ...`` with the way to register one
    """
    if not isinstance(env_id, str) or ":" in env_id or env_id not in gym.registry:
        ours = ", ".join(sorted(i for i in gym.registry if i.startswith("DSS14")))
        raise ValueError(f"{source}: field '{field}': {env_id!r} is not a registered environment "
                         f"id (DSS14 ids: {ours}); "
                         f"an environment of your own: import the module that registers it "
                         f"(dss14 train --env-module MODULE)")


def resolve_env(cfg: TrainConfig) -> EnvPlan:
    """The base environment and interface of a configuration.

    :raises ValueError: ``frame_stack`` on a wrapper id (use its ``history``) or on a
        non-DSS14 environment
    """
    import_env_module(cfg.env_id, cfg.env_module)
    check_registered(cfg.env_id, cfg.source, "env_id")
    kw = dict(cfg.env_kwargs)
    if cfg.env_id in WRAPPER_IDS:
        check_registered(kw.get("base_id", DEFAULT_BASE_ID), cfg.source, "env_kwargs.base_id")
        if cfg.frame_stack:
            raise ValueError(f"{cfg.source}: key 'frame_stack': {cfg.env_id} has its own history; "
                             f"set env_kwargs.history instead")
        base_id = kw.pop("base_id", DEFAULT_BASE_ID)
        try:
            spec, base_kw = spec_from_kwargs(kw, WRAPPER_IDS[cfg.env_id])
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{cfg.source}: key 'env_kwargs': {exc}") from None
        return EnvPlan(base_id, base_kw, spec, True)
    dss = is_dss14_id(cfg.env_id)
    if cfg.frame_stack:
        if not dss:
            raise ValueError(f"{cfg.source}: key 'frame_stack': only for DSS14 environments, "
                             f"got {cfg.env_id!r}")
        return EnvPlan(cfg.env_id, kw, InterfaceSpec(history=cfg.frame_stack), True)
    return EnvPlan(cfg.env_id, kw, None, dss)


def make_env(env_id: str, env_kwargs: Mapping[str, Any] | None = None,
             env_module: str | None = None) -> Any:
    """``gymnasium.make(env_id, **env_kwargs)`` after importing the registering module
    (module-level, so that ``SubprocVecEnv`` workers can call it).
    """
    import_env_module(env_id, env_module)
    return gym.make(env_id, **dict(env_kwargs or {}))


def make_plan_env(plan: EnvPlan, extra: Mapping[str, Any] | None = None) -> Any:
    """One environment of a plan (the base environment, the interface wrapper on top)."""
    env = gym.make(plan.base_id, **{**plan.base_kwargs, **dict(extra or {})})
    return env if plan.interface is None else InterfaceWrapper(env, plan.interface)


def check_env(cfg: TrainConfig) -> tuple[EnvPlan, Any, Any, Any]:
    """Make one training environment in this process: a clear error early, and its spaces.

    :return: ``(plan, policy observation space, action space, base env config or None)``
    :raises ValueError: naming ``env_id`` / ``env_kwargs`` / ``eval_env_kwargs``
    """
    try:
        plan = resolve_env(cfg)
        env = make_plan_env(plan)
    except Exception as exc:  # gymnasium.error.*, TypeError from bad env_kwargs, ImportError
        if isinstance(exc, ValueError) and str(exc).startswith(cfg.source):
            raise
        raise ValueError(f"{cfg.source}: key 'env_id': cannot make {cfg.env_id!r} with env_kwargs "
                         f"{cfg.env_kwargs}: {type(exc).__name__}: {exc}") from exc
    try:
        spaces_ = env.observation_space, env.action_space
        env_config = getattr(env.unwrapped, "config", None) if plan.dss14 else None
    finally:
        env.close()
    if cfg.eval_env_kwargs and not plan.dss14:
        kw = {**cfg.env_kwargs, **cfg.eval_env_kwargs}
        try:
            make_env(cfg.env_id, kw, cfg.env_module).close()
        except Exception as exc:  # noqa: BLE001 - same as above, for the evaluation environment
            raise ValueError(f"{cfg.source}: key 'eval_env_kwargs': cannot make {cfg.env_id!r} "
                             f"with {kw}: {type(exc).__name__}: {exc}") from exc
    return plan, spaces_[0], spaces_[1], env_config


def _interface_env(base_id: str, base_kwargs: dict, spec: InterfaceSpec) -> Any:
    return InterfaceWrapper(gym.make(base_id, **base_kwargs), spec)


#: the configuration keys every part of a mixture must share with the interface's environment
MIXTURE_SHARED_KEYS = ("dt", "action_scale_deg_s", "rate_limit_deg_s", "error_scale_mdeg")


def is_dss14_id(env_id: str) -> bool:
    """Whether ``env_id`` is registered with the DSS14 vector entry point."""
    import dss14_env  # noqa: F401  (registers the ids)
    from dss14_env.envs.vector import DSS14VectorEnv

    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        return False
    ep = spec.vector_entry_point
    return ep is not None and str(ep).endswith("DSS14VectorEnv") or ep is DSS14VectorEnv


def make_mixture_vec_env(mixture: list[dict[str, Any]], common: Mapping[str, Any], seed: int | None,
                         env_config: Any, source: str = "<config>") -> MixtureVecEnv:
    """The batched VecEnv of a ``mixture`` (:func:`dss14_env.agents.config`'s checked parts):
    one :class:`~dss14_env.agents.vec_env.SB3VecEnv` per part -- its preset's registration, the
    ``common`` keys laid over, then the part's own ``env_kwargs`` -- side by side
    (:class:`~dss14_env.agents.vec_env.MixtureVecEnv`); sub-environment ``i`` seeded ``seed + i``.

    :param env_config: the configuration the policy interface is built for: every part must
        share its :data:`MIXTURE_SHARED_KEYS`
    :raises ValueError: a part whose environment differs in those keys, naming it
    """
    from dss14_env.agents.vec_env import MixtureVecEnv, make_sb3_vec_env
    from dss14_env.envs.presets import PRESETS

    kw = dict(common)
    default_steps = kw.pop("max_episode_steps", None)
    parts, names = [], []
    for k, part in enumerate(mixture):
        preset = PRESETS[part["preset"]]
        steps = part["max_episode_steps"] or default_steps or preset.max_episode_steps
        venv = make_sb3_vec_env(preset.env_id, part["n_envs"], max_episode_steps=steps,
                                **{**kw, **part["env_kwargs"]})
        cfg = venv.venv.config
        bad = [key for key in MIXTURE_SHARED_KEYS
               if env_config is not None and getattr(cfg, key) != getattr(env_config, key)]
        if bad:
            raise ValueError(f"{source}: key 'mixture[{k}]': {bad[0]} is {getattr(cfg, bad[0])!r} in "
                             f"{part['preset']}, {getattr(env_config, bad[0])!r} in the policy's "
                             f"environment: the parts must share {', '.join(MIXTURE_SHARED_KEYS)}")
        parts.append(venv)
        names.append(part["preset"])
    mix = MixtureVecEnv(parts, names)
    if seed is not None:
        mix.seed(seed)
    return mix


def vec_env_kind(cfg: TrainConfig, plan: EnvPlan) -> str:
    """``batched``, ``dummy`` or ``subproc`` (``auto``: batched for DSS14 environments)."""
    if cfg.vec_env == "auto":
        return "batched" if plan.dss14 else "dummy"
    if cfg.vec_env == "batched" and not plan.dss14:
        raise ValueError(f"{cfg.source}: key 'vec_env': batched needs a DSS14 environment, "
                         f"{cfg.env_id!r} is not one (use dummy or subproc)")
    return cfg.vec_env


def _wrap_batched(venv: Any, cfg: TrainConfig, plan: EnvPlan, env_config: Any,
                  monitor_dir: Path | None) -> Any:
    """A batched training VecEnv under a ``VecMonitor`` (``monitor_dir/monitor.csv``: the
    environment's returns), the action-change penalty (``action_change_penalty``), the
    logarithmic reward (``reward_log_scale``) and the interface.
    """
    from stable_baselines3.common.vec_env import VecMonitor

    from dss14_env.agents.vec_env import ActionChangePenaltyVecEnv, InterfaceVecEnv, LogRewardVecEnv

    inner = venv
    if monitor_dir is not None:
        monitor_dir.mkdir(parents=True, exist_ok=True)
    venv = VecMonitor(venv, None if monitor_dir is None else str(monitor_dir / "monitor.csv"))
    if cfg.action_change_penalty:
        venv = ActionChangePenaltyVecEnv(venv, cfg.action_change_penalty)
    if cfg.reward_log_scale is not None:
        venv = LogRewardVecEnv(venv, cfg.reward_log_scale, env_config, cfg.gamma, cfg.action_change_penalty)
    if plan.interface is None:
        return venv
    out = InterfaceVecEnv(venv, plan.interface, env_config)
    if reads_wind(plan):  # each row's base designed for its episode's reading
        from dss14_env.agents.wind_readings import wind_source

        out.interface.wind_source = wind_source(inner)
    return out


def reads_wind(plan: EnvPlan) -> bool:
    """Whether the plan's interface reads the rows' wind readings (a base scheduled on them, or
    the ``wind_reading`` context).
    """
    spec = plan.interface
    return spec is not None and (spec.base == SCHEDULED_BASE or READING_CONTEXT in spec.context)


def monitor_files(cfg: TrainConfig, plan: EnvPlan, monitor_dir: Path) -> list[Path]:
    """The files the training VecEnv's monitors write in ``monitor_dir``
    (:func:`make_train_vec_env`): ``monitor.csv`` batched, else ``<i>.monitor.csv`` per copy.
    """
    if cfg.mixture or vec_env_kind(cfg, plan) == "batched":
        return [monitor_dir / "monitor.csv"]
    return [monitor_dir / f"{i}.monitor.csv" for i in range(cfg.n_envs)]


def make_train_vec_env(cfg: TrainConfig, plan: EnvPlan, env_config: Any,
                       monitor_dir: Path | None) -> Any:
    """The training VecEnv (before normalisation); sub-environment ``i`` seeded ``seed + i``.

    Batched: one :class:`~dss14_env.agents.vec_env.SB3VecEnv` under a ``VecMonitor``
    (``monitor_dir/monitor.csv``) and the interface. Otherwise SB3's ``make_vec_env`` with a
    ``Monitor`` per copy (``monitor_dir/<i>.monitor.csv``).
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    from dss14_env.agents.vec_env import make_sb3_vec_env, make_subproc_vec_env

    kind = vec_env_kind(cfg, plan)
    if cfg.mixture:
        if kind != "batched":
            raise ValueError(f"{cfg.source}: key 'mixture': needs the batched VecEnv (vec_env: auto "
                             f"or batched on a DSS14 environment)")
        venv = make_mixture_vec_env(cfg.mixture, plan.base_kwargs, cfg.seed, env_config, cfg.source)
        return _wrap_batched(venv, cfg, plan, env_config, monitor_dir)
    if kind == "batched":
        kw = dict(plan.base_kwargs)
        steps = kw.pop("max_episode_steps", None)
        venv = make_sb3_vec_env(plan.base_id, cfg.n_envs, seed=cfg.seed, max_episode_steps=steps, **kw)
        return _wrap_batched(venv, cfg, plan, env_config, monitor_dir)
    if cfg.action_change_penalty:
        raise ValueError(f"{cfg.source}: key 'action_change_penalty': needs the batched VecEnv "
                         f"(vec_env: auto or batched on a DSS14 environment)")
    if plan.interface is not None and cfg.env_id not in WRAPPER_IDS:
        factory = functools.partial(_interface_env, plan.base_id, dict(plan.base_kwargs),
                                    plan.interface)
    else:
        factory = functools.partial(make_env, cfg.env_id, cfg.env_kwargs, cfg.env_module)
    return make_vec_env(factory, n_envs=cfg.n_envs, seed=cfg.seed,
                        monitor_dir=None if monitor_dir is None else str(monitor_dir),
                        vec_env_cls=make_subproc_vec_env if kind == "subproc" else DummyVecEnv)


__all__ = ["DEFAULT_BASE_ID", "DEFAULT_ENV_MODULES", "EnvPlan", "WRAPPER_IDS", "check_env", "is_dss14_id",
           "check_registered",
           "import_env_module", "make_env", "make_plan_env", "make_train_vec_env",
           "make_kalman_obs_env", "make_mixture_vec_env", "make_plain_env", "make_residual_lqg_env",
           "make_wrapped_env",
           "resolve_env", "vec_env_kind"]
