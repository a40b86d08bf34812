r"""Hyperparameters as data per environment id, in rl-zoo3's format.

``configs/hyperparams/<algo>.yml`` (shipped as package data) maps environment ids to the
hyperparameters of one algorithm, exactly as rl-baselines3-zoo's files do, so both work::

    dss14 train ppo --env DSS14-Hold-v0                    # this package's trainer
    python -m rl_zoo3.train --algo ppo --env DSS14-Hold-v0 --gym-packages dss14_env \
        -conf "$(python -m dss14_env.agents.hyperparams ppo)"      # prints the file's path

Keys understood here: ``n_envs``, ``n_timesteps``, ``policy`` (``MlpPolicy`` /
``MlpLstmPolicy``), ``normalize`` (true/false, a mapping or rl-zoo3's string
``"dict(norm_obs=True, norm_reward=False)"``), ``env_kwargs``, ``policy_kwargs`` (a mapping,
or rl-zoo3's ``"dict(...)"`` string: ``net_arch``, ``activation_fn`` as ``nn.Tanh`` etc.,
``log_std_init``, the LSTM sizes) and the algorithm's hyperparameters by their SB3 names.
Strings are parsed, never evaluated; the file is read by ``read_config`` (YAML 1.2).  The keys of a
run that rl-zoo3 does not know (seeds, evaluation, checkpoints) take this package's defaults.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from dss14_env.agents.config import TrainConfig, check_file_imports
from dss14_env.core.schema import read_config

_ACT = {"nn.Tanh": "tanh", "nn.ReLU": "relu", "nn.ELU": "elu", "nn.LeakyReLU": "leaky_relu",
        "th.nn.Tanh": "tanh", "th.nn.ReLU": "relu", "th.nn.ELU": "elu", "th.nn.LeakyReLU": "leaky_relu"}
_POLICY_KW = ("net_arch", "activation_fn", "log_std_init", "lstm_hidden_size", "n_lstm_layers",
              "shared_lstm", "enable_critic_lstm")
_POLICIES = {"ppo": "MlpPolicy", "sac": "MlpPolicy", "recurrent_ppo": "MlpLstmPolicy"}


def hyperparams_path(algo: str) -> Path:
    """The shipped hyperparameter file of ``algo`` (``configs/hyperparams/<algo>.yml``)."""
    return Path(str(resources.files("dss14_env.configs").joinpath("hyperparams", f"{algo}.yml")))


def _literal(node: ast.AST, where: str) -> Any:
    if isinstance(node, ast.Attribute):  # nn.Tanh
        name = ast.unparse(node)
        if name in _ACT:
            return _ACT[name]
        raise ValueError(f"{where}: {name!r} is not an activation this package knows")
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" \
            and not node.args:
        return {kw.arg: _literal(kw.value, where) for kw in node.keywords}
    if isinstance(node, ast.List):
        return [_literal(e, where) for e in node.elts]
    if isinstance(node, ast.Dict):
        return {_literal(k, where): _literal(v, where) for k, v in zip(node.keys, node.values,
                                                                       strict=True)}
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise ValueError(f"{where}: cannot read {ast.unparse(node)!r} (only literals, dict(...) "
                         f"and nn.<Activation> are read; nothing is evaluated)") from None


def parse_zoo_value(text: str, where: str) -> Any:
    """An rl-zoo3 string value (``"dict(net_arch=[64, 64], activation_fn=nn.ReLU)"``), parsed
    without evaluating it.
    """
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError:
        raise ValueError(f"{where}: not a Python literal: {text!r}") from None
    return _literal(tree.body, where)


def _normalize(v: Any, where: str) -> dict[str, bool]:
    norm = parse_zoo_value(v, f"{where}: key 'normalize'") if isinstance(v, str) else v
    if isinstance(norm, bool):
        return {"normalize_obs": norm, "normalize_reward": norm}
    if isinstance(norm, Mapping) and set(norm) <= {"norm_obs", "norm_reward", "gamma"}:
        return {"normalize_obs": bool(norm.get("norm_obs", True)),
                "normalize_reward": bool(norm.get("norm_reward", True))}
    raise ValueError(f"{where}: key 'normalize' must be true/false or dict(norm_obs=..., "
                     f"norm_reward=...), got {v!r}")


def _policy_kwargs(v: Any, where: str) -> dict[str, Any]:
    pk = parse_zoo_value(v, f"{where}: key 'policy_kwargs'") if isinstance(v, str) else v
    if not isinstance(pk, Mapping):
        raise ValueError(f"{where}: key 'policy_kwargs' must be a mapping, got {v!r}")
    out = {}
    for k, x in pk.items():
        if k not in _POLICY_KW:
            raise ValueError(f"{where}: key 'policy_kwargs.{k}' is not one this package reads "
                             f"({', '.join(_POLICY_KW)})")
        out[k] = _ACT.get(x, x) if k == "activation_fn" else x
    return out


def zoo_to_config(algo: str, env_id: str, hp: Mapping[str, Any], source: str) -> TrainConfig:
    """A :class:`TrainConfig` from one rl-zoo3 hyperparameter entry.

    :raises ValueError: unknown key or bad value, naming the entry's key and ``source``
    """
    where = f"{source}: {env_id}"
    out: dict[str, Any] = {"algo": algo, "env_id": env_id}
    for key, v in hp.items():
        if key == "n_timesteps":
            out["total_timesteps"] = v
        elif key == "policy":
            if v != _POLICIES[algo]:
                raise ValueError(f"{where}: key 'policy' must be {_POLICIES[algo]!r} for {algo}, "
                                 f"got {v!r}")
        elif key == "normalize":
            out.update(_normalize(v, where))
        elif key == "policy_kwargs":
            out.update(_policy_kwargs(v, where))
        else:
            out[key] = v
    return TrainConfig.from_dict(out, source=where)


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> TrainConfig:
    """The configuration of ``algo`` on ``env_id`` from a hyperparameter file.

    :param algo: ``ppo``, ``recurrent_ppo`` or ``sac``
    :param env_id: the entry
    :param path: the file, default None: :func:`hyperparams_path`
    :raises ValueError: missing file or entry (naming the ids it has), bad values
    """
    p = Path(path) if path is not None else hyperparams_path(algo)
    data, _ = read_config(p)
    if env_id not in data:
        raise ValueError(f"{p}: no hyperparameters for {env_id!r}; entries: {', '.join(data)}")
    entry = data[env_id]
    if not isinstance(entry, Mapping):
        raise ValueError(f"{p}: entry {env_id!r} must be a mapping")
    return check_file_imports(zoo_to_config(algo, env_id, entry, str(p)))


__all__ = ["hyperparams_path", "load_hyperparams", "parse_zoo_value", "zoo_to_config"]

if __name__ == "__main__":  # python -m dss14_env.agents.hyperparams <algo>: the file's path
    import sys

    print(hyperparams_path(sys.argv[1] if len(sys.argv) > 1 else "ppo"))
