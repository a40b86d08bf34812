"""The training configuration of every algorithm: one typed, validated :class:`TrainConfig`.

A configuration is a flat mapping (YAML) of the keys every run has (environment, budget,
seeding, normalisation, evaluation, checkpoints) and the hyperparameters of its algorithm
(``algo``: ``ppo``, ``recurrent_ppo`` (sb3-contrib ``RecurrentPPO``) or ``sac``), with the
stable-baselines3 names.  Keys left out take the algorithm's defaults (:data:`ALGO_FIELDS`);
an unknown key, a key of another algorithm or a bad value raises :class:`ValueError` naming
the key and the file.  Shipped configurations are addressable by name
(:func:`resolve_config_path`: ``ppo_plain`` is ``configs/ppo_plain.yaml``); a path works too.

>>> cfg = TrainConfig.from_dict({"env_id": "Pendulum-v1", "n_envs": 2, "n_steps": 64,
...                              "batch_size": 64})
>>> cfg.algo, cfg.n_envs, cfg.n_steps, cfg.vec_env
('ppo', 2, 64, 'auto')
>>> TrainConfig.from_dict({"env_id": "Pendulum-v1", "n_env": 2})
Traceback (most recent call last):
...
ValueError: <dict>: unknown key 'n_env' (did you mean 'n_envs'?)
>>> TrainConfig.from_dict({"algo": "sac", "n_epochs": 3})
Traceback (most recent call last):
...
ValueError: <dict>: key 'n_epochs' is not a setting of algo 'sac' (it belongs to ppo, recurrent_ppo)
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

#: the algorithms ``dss14 train`` knows
ALGOS = ("ppo", "recurrent_ppo", "sac")
ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")
#: ``auto``: ``batched`` for DSS14 ids (:mod:`dss14_env.agents.vec_env`), ``dummy`` otherwise
VEC_ENVS = ("auto", "batched", "dummy", "subproc")


@dataclass(frozen=True)
class Field:
    """The spec of one configuration key.

    :param kind: ``int``, ``float``, ``bool``, ``choice``, ``str``, ``mapping``, ``layers``
        (list of layer sizes or ``{pi, vf}`` / ``{pi, qf}``), ``seeds`` (non-empty list of
        integers >= 0), ``float_or_auto`` (a number or the string ``auto``)
    :param default: value when the key is left out
    :param lo: lower bound (numbers), default None
    :param hi: upper bound, default None
    :param lo_open: the lower bound is excluded, default False
    :param choices: allowed strings (``choice``)
    :param nullable: None is allowed, default False
    """

    kind: str
    default: Any
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple[str, ...] = ()
    nullable: bool = False


#: keys of every run
COMMON_FIELDS: dict[str, Field] = {
    "algo": Field("choice", "ppo", choices=ALGOS),
    "env_id": Field("str", "DSS14-v0"),
    "env_kwargs": Field("mapping", {}),
    "env_module": Field("str", None, nullable=True),
    "frame_stack": Field("int", 0, lo=0),
    "n_envs": Field("int", 8, lo=1),
    "vec_env": Field("choice", "auto", choices=VEC_ENVS),
    "total_timesteps": Field("int", 2_000_000, lo=1),
    "seed": Field("int", 10_000, lo=0),
    "normalize_obs": Field("bool", True),
    "normalize_reward": Field("bool", True),
    "learning_rate": Field("float", 3e-4, lo=0.0, lo_open=True),
    "gamma": Field("float", 0.99, lo=0.0, hi=1.0, lo_open=True),
    "net_arch": Field("layers", [64, 64]),
    "activation_fn": Field("choice", "tanh", choices=ACTIVATIONS),
    "log_std_init": Field("float", -0.5, lo=-20.0, hi=5.0),
    "eval_freq": Field("int", 50_000, lo=0),
    "n_eval_episodes": Field("int", 1, lo=1),
    "eval_seeds": Field("seeds", [1000, 1001, 1002, 1003, 1004]),
    "eval_env_kwargs": Field("mapping", {}),
    "eval_episode_steps": Field("int", 1000, lo=1),
    "checkpoint_freq": Field("int", 200_000, lo=0),
    "torch_threads": Field("int", 1, lo=1),
    "progress_bar": Field("bool", True),
    "verbose": Field("int", 1, lo=0, hi=2),
}

_PPO = {
    "n_steps": Field("int", 256, lo=1),
    "batch_size": Field("int", 256, lo=2),
    "n_epochs": Field("int", 10, lo=1),
    "gae_lambda": Field("float", 0.95, lo=0.0, hi=1.0),
    "clip_range": Field("float", 0.2, lo=0.0, lo_open=True),
    "ent_coef": Field("float", 0.0, lo=0.0),
    "vf_coef": Field("float", 0.5, lo=0.0),
    "max_grad_norm": Field("float", 0.5, lo=0.0, lo_open=True),
    "target_kl": Field("float", None, lo=0.0, lo_open=True, nullable=True),
}
_RECURRENT = {
    "lstm_hidden_size": Field("int", 64, lo=1),
    "n_lstm_layers": Field("int", 1, lo=1),
    "shared_lstm": Field("bool", False),
    "enable_critic_lstm": Field("bool", True),
}
_SAC = {
    "buffer_size": Field("int", 1_000_000, lo=1),
    "learning_starts": Field("int", 10_000, lo=0),
    "batch_size": Field("int", 256, lo=1),
    "tau": Field("float", 0.005, lo=0.0, hi=1.0, lo_open=True),
    "train_freq": Field("int", 1, lo=1),
    "gradient_steps": Field("int", 1, lo=-1),
    "ent_coef": Field("float_or_auto", "auto", lo=0.0, lo_open=True),
    "target_entropy": Field("float_or_auto", "auto"),
    "save_replay_buffer": Field("bool", True),
}

#: the hyperparameter keys of each algorithm (on top of :data:`COMMON_FIELDS`)
ALGO_FIELDS: dict[str, dict[str, Field]] = {
    "ppo": dict(_PPO),
    "recurrent_ppo": {**_PPO, **_RECURRENT},
    "sac": dict(_SAC),
}
#: defaults of common keys that differ per algorithm (SB3's own defaults for SAC)
ALGO_DEFAULTS: dict[str, dict[str, Any]] = {
    "ppo": {},
    "recurrent_ppo": {},
    "sac": {"net_arch": [256, 256], "activation_fn": "relu", "log_std_init": -3.0, "n_envs": 1},
}


def fields_of(algo: str) -> dict[str, Field]:
    """Every key of a configuration of ``algo`` with its spec (defaults of that algorithm)."""
    out = dict(COMMON_FIELDS)
    out.update(ALGO_FIELDS[algo])
    for k, v in ALGO_DEFAULTS[algo].items():
        f = out[k]
        out[k] = Field(f.kind, v, f.lo, f.hi, f.lo_open, f.choices, f.nullable)
    return out


def _all_keys() -> set[str]:
    keys = set(COMMON_FIELDS)
    for f in ALGO_FIELDS.values():
        keys |= set(f)
    return keys


# ------------------------------------------------------------------------------ validation
def _bad(source: str, key: str, msg: str, value: Any) -> ValueError:
    return ValueError(f"{source}: key {key!r}: {msg}, got {value!r}")


def _number(v: Any) -> Any:
    if isinstance(v, str):  # PyYAML reads "3e-4" (no dot) as a string
        try:
            return float(v)
        except ValueError:
            return v
    return v


def _layers(v: Any, key: str, source: str) -> list[int]:
    if not isinstance(v, (list, tuple)) or not all(
            isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1 for n in v):
        raise _bad(source, key, "must be a list of layer sizes (integers >= 1)", v)
    return [int(n) for n in v]


def _range_text(f: Field) -> str:
    rng = []
    if f.lo is not None:
        rng.append(f"> {f.lo:g}" if f.lo_open else f">= {f.lo:g}")
    if f.hi is not None:
        rng.append(f"<= {f.hi:g}")
    return (" " + " and ".join(rng)) if rng else ""


def _check_int(key: str, f: Field, v: Any, source: str) -> int:
    v = _number(v)
    if isinstance(v, float) and v.is_integer():  # 1e6 in YAML
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or \
            (f.lo is not None and v < f.lo) or (f.hi is not None and v > f.hi):
        raise _bad(source, key, f"must be an integer{_range_text(f)}", v)
    return int(v)


def _check_float(key: str, f: Field, v: Any, source: str) -> float | str:
    if f.kind == "float_or_auto" and v == "auto":
        return "auto"
    v = _number(v)
    what = "a finite number" + (" or 'auto'" if f.kind == "float_or_auto" else "")
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise _bad(source, key, f"must be {what}{_range_text(f)}", v)
    x = float(v)
    if (not math.isfinite(x) or (f.lo is not None and (x <= f.lo if f.lo_open else x < f.lo))
            or (f.hi is not None and x > f.hi)):
        raise _bad(source, key, f"must be {what}{_range_text(f)}", v)
    return x


def _check_bool(key: str, f: Field, v: Any, source: str) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise _bad(source, key, "must be true or false", v)
    return bool(v)


def _check_choice(key: str, f: Field, v: Any, source: str) -> str:
    if not isinstance(v, str) or v not in f.choices:
        raise _bad(source, key, f"must be one of {', '.join(f.choices)}", v)
    return v


def _check_str(key: str, f: Field, v: Any, source: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _bad(source, key, "must be a non-empty string", v)
    return v


def _check_mapping(key: str, f: Field, v: Any, source: str) -> dict:
    if not isinstance(v, Mapping) or not all(isinstance(k, str) for k in v):
        raise _bad(source, key, "must be a mapping of keyword arguments", v)
    return json.loads(json.dumps(dict(v), default=_plain))


def _check_layers(key: str, f: Field, v: Any, source: str) -> Any:
    if isinstance(v, Mapping):
        if set(v) not in ({"pi", "vf"}, {"pi", "qf"}):
            raise _bad(source, key, "a mapping must have exactly the keys pi and vf (or pi and "
                       "qf for sac)", v)
        return {k: _layers(v[k], f"{key}.{k}", source) for k in sorted(v)}
    return _layers(v, key, source)


def _check_seeds(key: str, f: Field, v: Any, source: str) -> list[int]:
    if not isinstance(v, (list, tuple)) or not v:
        raise _bad(source, key, "must be a non-empty list of integers >= 0", v)
    return [_check_int(key, Field("int", 0, lo=0), s, source) for s in v]


_CHECKS = {"int": _check_int, "float": _check_float, "float_or_auto": _check_float,
           "bool": _check_bool, "choice": _check_choice, "str": _check_str,
           "mapping": _check_mapping, "layers": _check_layers, "seeds": _check_seeds}


def check_value(key: str, f: Field, v: Any, source: str) -> Any:
    """The validated, normalised value of one key (raises ValueError naming key and source)."""
    if v is None:
        if f.nullable:
            return None
        raise _bad(source, key, "must not be null", v)
    return _CHECKS[f.kind](key, f, v, source)


def _plain(o: Any) -> Any:
    return o.item() if hasattr(o, "item") else str(o)


class TrainConfig:
    """Everything one training run needs (see the module doc and ``docs/rl.md``).

    Read the values as attributes (``cfg.n_steps``); build with :meth:`from_dict` or
    :func:`load_config`; change with :meth:`replace` (validated again).

    :param values: key -> value; missing keys take the defaults of ``values["algo"]``
    :param source: file the values came from (error messages only)
    """

    __slots__ = ("_values", "source")

    def __init__(self, values: Mapping[str, Any] | None = None, source: str = "<dict>") -> None:
        values = dict(values or {})
        object.__setattr__(self, "source", source)
        algo = values.get("algo", "ppo")
        algo = check_value("algo", COMMON_FIELDS["algo"], algo, source)
        spec = fields_of(algo)
        known = _all_keys()
        for key in values:
            if key not in known:
                near = difflib.get_close_matches(str(key), sorted(known), n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise ValueError(f"{source}: unknown key {key!r}{hint}")
            if key not in spec:
                owners = [a for a, fs in ALGO_FIELDS.items() if key in fs]
                raise ValueError(f"{source}: key {key!r} is not a setting of algo {algo!r} "
                                 f"(it belongs to {', '.join(owners)})")
        out = {}
        for key, f in spec.items():
            v = values.get(key, f.default)
            out[key] = check_value(key, f, v, source)
        self._cross_checks(out, source)
        object.__setattr__(self, "_values", out)

    @staticmethod
    def _cross_checks(c: dict[str, Any], source: str) -> None:
        if c["algo"] in ("ppo", "recurrent_ppo"):
            rollout = c["n_steps"] * c["n_envs"]
            if c["batch_size"] > rollout or rollout % c["batch_size"]:
                raise _bad(source, "batch_size", f"must divide n_steps * n_envs = {rollout}",
                           c["batch_size"])
        if isinstance(c["net_arch"], dict):
            want = {"pi", "qf"} if c["algo"] == "sac" else {"pi", "vf"}
            if set(c["net_arch"]) != want:
                raise _bad(source, "net_arch", f"a mapping must have exactly the keys "
                           f"{' and '.join(sorted(want))} for {c['algo']}", c["net_arch"])

    # -- access -----------------------------------------------------------------------------
    def __getattr__(self, name: str) -> Any:
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no key {name!r}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("TrainConfig is immutable; use replace()")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, TrainConfig) and self._values == other._values

    def __hash__(self) -> int:
        return hash(json.dumps(self._values, sort_keys=True))

    def __repr__(self) -> str:
        return f"TrainConfig({self._values!r})"

    def __reduce__(self) -> Any:  # SubprocVecEnv workers receive the config
        return (TrainConfig, (self._values, self.source))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> TrainConfig:
        """A validated config from a mapping; missing keys take their defaults.

        :raises ValueError: unknown key or bad value, naming the key and ``source``
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a mapping of training settings, got "
                             f"{type(data).__name__}")
        return cls(data, source)

    def replace(self, source: str | None = None, **changes: Any) -> TrainConfig:
        """Copy with some values changed (validated again), e.g. ``cfg.replace(seed=3)``.

        Changing ``algo`` keeps only the keys the new algorithm has.
        """
        values = dict(self._values)
        if "algo" in changes and changes["algo"] != values["algo"]:
            keep = fields_of(check_value("algo", COMMON_FIELDS["algo"], changes["algo"],
                                         source or self.source))
            values = {k: v for k, v in values.items() if k in keep and k in COMMON_FIELDS
                      and k not in ALGO_DEFAULTS[changes["algo"]]}
        values.update(changes)
        return TrainConfig(values, source or self.source)

    def to_dict(self) -> dict[str, Any]:
        """Plain-YAML mapping of every key (loads back with :meth:`from_dict`)."""
        return json.loads(json.dumps(self._values, default=_plain))


#: the name of the earlier PPO-only configuration class
PPOConfig = TrainConfig


# ------------------------------------------------------------------------------ files
def shipped_config_path(name: str) -> Path:
    """Path of a configuration file shipped in the ``configs`` package (``ppo.yaml``)."""
    return Path(str(resources.files("dss14_env.configs").joinpath(name)))


def default_config_path(name: str = "ppo.yaml") -> Path:
    """Path of a training configuration shipped in the ``configs`` package.

    :param name: file name, default ``"ppo.yaml"`` (``"ppo_smoke.yaml"``: Pendulum-v1 smoke run)
    """
    return shipped_config_path(name)


def resolve_config_path(name_or_path: str | Path) -> Path:
    """A configuration file by path, or a shipped one by name (``ppo_plain`` or
    ``ppo_plain.yaml`` -> ``configs/ppo_plain.yaml``).

    :raises ValueError: neither a file nor a shipped name
    """
    p = Path(name_or_path)
    if p.is_file():
        return p
    if p.parent == Path(".") and not p.is_absolute():
        for cand in (p.name, f"{p.name}.yaml"):
            q = shipped_config_path(cand)
            if q.is_file():
                return q
    raise ValueError(f"training config file not found: {p} (and no shipped config of that "
                     f"name; shipped: {', '.join(shipped_training_configs())})")


def shipped_training_configs() -> list[str]:
    """Names of the shipped training configurations (``configs/ppo*.yaml`` etc.)."""
    root = resources.files("dss14_env.configs")
    return sorted(p.name[:-5] for p in root.iterdir()
                  if p.name.endswith(".yaml") and p.name.split("_")[0].split(".")[0] in
                  ("ppo", "sac", "recurrent"))


def read_yaml_mapping(p: Path, what: str = "training config") -> dict[str, Any]:
    """A YAML file's top-level mapping (``yaml.safe_load``); errors name the file."""
    if not p.is_file():
        raise ValueError(f"{what} file not found: {p}")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{p}: not valid YAML: {exc}".replace("\n", " ")) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{p}: cannot read the file ({exc})") from exc
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ValueError(f"{p}: expected a mapping of training settings, got {type(data).__name__}")
    return dict(data)


def load_config(path: str | Path | None = None) -> TrainConfig:
    """Read and validate a training YAML file.

    :param path: the file or a shipped config's name, default None: the shipped
        ``configs/ppo.yaml``
    :raises ValueError: missing/unreadable file, unknown key or bad value (names key and file)
    """
    p = resolve_config_path(path) if path is not None else default_config_path()
    return TrainConfig.from_dict(read_yaml_mapping(p), source=str(p))


def as_config(config: TrainConfig | Mapping[str, Any] | str | Path) -> TrainConfig:
    """A :class:`TrainConfig` from a config, a mapping or a YAML path (or shipped name)."""
    if isinstance(config, TrainConfig):
        return config
    if isinstance(config, Mapping):
        return TrainConfig.from_dict(config)
    if isinstance(config, (str, Path)):
        return load_config(config)
    raise ValueError(f"config must be a TrainConfig, a mapping or a YAML path, got "
                     f"{type(config).__name__}")


__all__ = ["ACTIVATIONS", "ALGOS", "ALGO_DEFAULTS", "ALGO_FIELDS", "COMMON_FIELDS", "Field",
           "PPOConfig", "TrainConfig", "VEC_ENVS", "as_config", "check_value",
           "default_config_path", "fields_of", "load_config", "read_yaml_mapping",
           "resolve_config_path", "shipped_config_path", "shipped_training_configs"]
