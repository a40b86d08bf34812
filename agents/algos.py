"""The algorithms of ``dss14 train``: their stable-baselines3 classes and keyword arguments,
and the policy network rebuilt from a run's configuration (for loading without unpickling).

``ppo``: :class:`stable_baselines3.PPO`; ``recurrent_ppo``: :class:`sb3_contrib.RecurrentPPO`
(LSTM policy; needs ``sb3-contrib``, the ``rl`` extra); ``sac``: :class:`stable_baselines3.SAC`.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np

from dss14_env.agents.config import TrainConfig

#: keys of the config that are passed to the algorithm's constructor, per algorithm
_ALGO_KW = {
    "ppo": ("learning_rate", "n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda",
            "clip_range", "ent_coef", "vf_coef", "max_grad_norm", "target_kl"),
    "sac": ("learning_rate", "buffer_size", "learning_starts", "batch_size", "tau", "gamma",
            "train_freq", "gradient_steps", "ent_coef", "target_entropy"),
}
_ALGO_KW["recurrent_ppo"] = _ALGO_KW["ppo"]


def algo_class(algo: str) -> Any:
    """The SB3 class of ``algo``.

    :raises ValueError: unknown algorithm, or sb3-contrib missing for ``recurrent_ppo``
    """
    if algo == "ppo":
        from stable_baselines3 import PPO

        return PPO
    if algo == "sac":
        from stable_baselines3 import SAC

        return SAC
    if algo == "recurrent_ppo":
        if importlib.util.find_spec("sb3_contrib") is None:
            raise ValueError("algo 'recurrent_ppo' needs sb3-contrib: pip install "
                             "'dss14-env[rl]' (or pip install sb3-contrib)")
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    raise ValueError(f"unknown algo {algo!r}; known: ppo, recurrent_ppo, sac")


def is_recurrent(algo: str) -> bool:
    """Whether the algorithm's policy keeps a hidden state (LSTM)."""
    return algo == "recurrent_ppo"


def policy_kwargs(cfg: TrainConfig) -> dict[str, Any]:
    """``policy_kwargs`` of the SB3 constructor (network architecture) from the config."""
    import torch.nn as nn

    act = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
    net_arch = dict(cfg.net_arch) if isinstance(cfg.net_arch, dict) else list(cfg.net_arch)
    kw: dict[str, Any] = {"net_arch": net_arch, "activation_fn": act[cfg.activation_fn],
                          "log_std_init": cfg.log_std_init}
    if is_recurrent(cfg.algo):
        kw.update(lstm_hidden_size=cfg.lstm_hidden_size, n_lstm_layers=cfg.n_lstm_layers,
                  shared_lstm=cfg.shared_lstm, enable_critic_lstm=cfg.enable_critic_lstm)
    return kw


def algo_kwargs(cfg: TrainConfig) -> dict[str, Any]:
    """Hyperparameters of the SB3 constructor from the config."""
    kw = {k: getattr(cfg, k) for k in _ALGO_KW[cfg.algo]}
    if cfg.algo == "sac" and kw["ent_coef"] != "auto":
        kw["ent_coef"] = float(kw["ent_coef"])
    return kw


class NoOptimizer:
    """The optimizer of a policy network built to act, not to learn (:func:`build_policy`): it
    holds nothing (a torch optimizer's first construction alone imports torch's compiler,
    about 2 s of a process).
    """

    def __init__(self, params: Any, lr: float = 0.0, **kwargs: Any) -> None:
        self.param_groups: list[dict[str, Any]] = []


def build_policy(cfg: TrainConfig, obs_dim: int, action_low: Any, action_high: Any) -> Any:
    """The algorithm's policy network, freshly initialised, for the config's architecture, to
    act (in evaluation mode, without an optimizer: :class:`NoOptimizer`).

    :param cfg: the run's configuration (``algo``, ``net_arch``, ``activation_fn``, ...)
    :param obs_dim: size of the policy's observation
    :param action_low: lower bounds of the action space
    :param action_high: upper bounds
    """
    from gymnasium import spaces

    cls = algo_class(cfg.algo)
    policy_cls = cls.policy_aliases["MlpLstmPolicy" if is_recurrent(cfg.algo) else "MlpPolicy"]
    obs_space = spaces.Box(-np.inf, np.inf, (int(obs_dim),), np.float32)
    act_space = spaces.Box(np.asarray(action_low, np.float32), np.asarray(action_high, np.float32),
                           dtype=np.float32)
    policy = policy_cls(obs_space, act_space, lambda _: 0.0, optimizer_class=NoOptimizer,
                        **policy_kwargs(cfg))
    policy.set_training_mode(False)
    return policy


__all__ = ["NoOptimizer", "algo_class", "algo_kwargs", "build_policy", "is_recurrent", "policy_kwargs"]
