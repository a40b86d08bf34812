"""The training configuration of every algorithm: one typed, validated :class:`TrainConfig`.

A configuration is a flat mapping (YAML) of the keys every run has (environment, budget,
seeding, normalisation, evaluation, checkpoints) and the hyperparameters of its algorithm
(``algo``: ``ppo``, ``recurrent_ppo`` (sb3-contrib ``RecurrentPPO``) or ``sac``), with the
stable-baselines3 names.  The fields and their checks are the project's configuration schema
(:mod:`dss14_env.core.schema`): :class:`PPOSettings`, :class:`RecurrentPPOSettings` and
:class:`SACSettings` (keys left out take that algorithm's defaults).  An unknown key, a key of
another algorithm or a bad value raises :class:`~dss14_env.core.schema.ConfigError` (a
ValueError) in the project's one style, ``<file>: field '<name>': ...``.  Shipped
configurations are addressable by name (``ppo_plain`` is ``configs/ppo_plain.yaml``); a path
works too.

A top-level ``sweep`` mapping (configuration keys -> lists of values) makes the file a
hyperparameter sweep: the grid of every combination of the values, each point the rest of the
file with those values set (:meth:`TrainConfig.points`; a dotted key such as
``env_kwargs.action_scale_deg_s`` sets one entry of a mapping).  Every point is validated as a
configuration of its own when the file is read; ``dss14 train --train-seeds`` trains one campaign per
point (:mod:`dss14_env.agents.sweep`).

>>> cfg = TrainConfig.from_dict({"env_id": "Pendulum-v1", "n_envs": 2, "n_steps": 64,
...                              "batch_size": 64})
>>> cfg.algo, cfg.n_envs, cfg.n_steps, cfg.vec_env
('ppo', 2, 64, 'auto')
>>> TrainConfig.from_dict({"env_id": "Pendulum-v1", "n_env": 2})  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: <dict>: top level: unknown field 'n_env' (did you mean 'n_envs'?); ...
>>> TrainConfig.from_dict({"algo": "sac", "n_epochs": 3})  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: <dict>: field 'n_epochs': is not a setting of algo 'sac' ...
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.agents.config_files import (
    shipped_config_path,
    shipped_training_configs,
    shipped_training_configs_by_algo,
)
from dss14_env.agents.evaluation import DEFAULT_SCENARIOS, SCENARIO_TASKS
from dss14_env.core.counts import MAX_THREADS
from dss14_env.core.schema import (
    ConfigError,
    Spec,
    check_value,
    field_spec,
    load_section,
    read_config,
    shipped_configs,
    spec,
)

#: the algorithms ``dss14 train`` knows
ALGOS = ("ppo", "recurrent_ppo", "sac")
ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")
#: what picks ``eval/best``: the highest mean validation return, or (DSS14) the lowest
#: geometric mean over the hold tasks of their mean validation 3σ servo error
#: (``three_sigma``) or 3σ pointing error (``pointing``), or over every validation scenario of
#: its figure (``general``: :func:`dss14_env.agents.train.general_figure`)
SELECT_BY = ("return", "three_sigma", "pointing", "general")
#: reference controllers an evaluation may have to beat on every validation task
#: (``select_reference``; :data:`dss14_env.agents.campaign_report.REFERENCES`)
SELECT_REFERENCES = ("pi_kp1", "lqg")
#: ``auto``: ``batched`` for DSS14 ids (:mod:`dss14_env.agents.vec_env`), ``dummy`` otherwise
VEC_ENVS = ("auto", "batched", "dummy", "subproc")

#: largest seed: numpy's legacy seeding (which stable-baselines3 calls) takes seeds below
#: 2^32, and a campaign adds 1000 k and each sub-environment its index to the seed
MAX_SEED = 2**31 - 1
#: largest layer of a network (and LSTM hidden size) and most layers: a 4096-wide layer of
#: 4096 inputs is 64 MiB of weights; beyond, torch fails to allocate or runs for hours
MAX_LAYER, MAX_LAYERS = 4096, 16
#: most sub-environments, steps of a rollout, threads and timesteps a configuration may ask for
#: (threads: the one bound of every command, dss14_env.core.counts.MAX_THREADS)
MAX_ENVS, MAX_ROLLOUT, MAX_TIMESTEPS = 1024, 10_000_000, 10**10
_INT = Spec("1", "integer", lo=0, hi=MAX_SEED)
#: the modules that register this package's environment ids, the only modules a configuration
#: file may name in ``env_module``: a fixed table, each name matched whole (another module of
#: the package, such as one inside a policy folder placed among the shipped ones, is refused)
KNOWN_ENV_MODULES = ("dss14_env", "dss14_env.agents", "dss14_env.agents.envs", "dss14_env.agents.residual")
#: keys a sweep cannot vary: the seeds come from ``--train-seeds``, the algorithm fixes the key set
NOT_SWEPT = ("algo", "seed", "sweep")
#: most points of a sweep's grid
MAX_SWEEP_POINTS = 1000
#: longest readable point label (a folder name); longer or clashing labels become ``point_NN``
MAX_LABEL_CHARS = 120


def _int(lo: int, default: int, hi: int | None = None) -> Any:
    return spec("1", kind="integer", lo=lo, hi=hi, default=default)


def _num(default: float | None, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, **kw: Any) -> Any:
    return spec("1", lo=lo, hi=hi, lo_open=lo_open, default=default, **kw)


def _test_scenarios(names: Any, source: str, key: str = "test_scenarios") -> list[str]:
    """The final test's (or the validation's) scenarios, each once (the schema checked each name)."""
    names = list(names)
    if len(set(names)) != len(names):
        raise ConfigError(f"{source}: field '{key}': each scenario once, got {names}")
    return names


def _flag(default: bool) -> Any:
    return spec(None, kind="bool", default=default)


@dataclass(frozen=True)
class CommonSettings:
    """The keys of every run (docs/rl.md explains each)."""

    algo: str = spec(None, kind="str", choices=ALGOS, default="ppo")
    env_id: str = spec(None, kind="str", default="DSS14-v0")
    env_kwargs: dict = spec(None, kind="mapping", default_factory=dict)
    env_module: str | None = spec(None, kind="str", optional=True, default=None)
    mixture: Any = spec(None, kind="any", default_factory=list)
    frame_stack: int = _int(0, 0, hi=1000)
    n_envs: int = _int(1, 8, hi=MAX_ENVS)
    vec_env: str = spec(None, kind="str", choices=VEC_ENVS, default="auto")
    total_timesteps: int = _int(1, 2_000_000, hi=MAX_TIMESTEPS)
    seed: int = _int(0, 10_000, hi=MAX_SEED)
    normalize_obs: bool = _flag(True)
    normalize_reward: bool = _flag(True)
    reward_log_scale: float | None = _num(None, lo=0.0, lo_open=True, hi=1.0e6, optional=True)
    action_change_penalty: float = _num(0.0, lo=0.0, hi=1.0e6)
    learning_rate: float = _num(3e-4, lo=0.0, lo_open=True)
    gamma: float = _num(0.99, lo=0.0, hi=1.0, lo_open=True)
    net_arch: Any = spec(None, kind="any", default_factory=lambda: [64, 64])
    activation_fn: str = spec(None, kind="str", choices=ACTIVATIONS, default="tanh")
    log_std_init: float = _num(-0.5, lo=-20.0, hi=5.0)
    eval_freq: int = _int(0, 50_000, hi=MAX_TIMESTEPS)
    n_eval_episodes: int = _int(1, 1, hi=1000)
    eval_seeds: tuple = spec("1", kind="list", items=_INT,
                             default=(1000, 1001, 1002, 1003, 1004))
    eval_env_kwargs: dict = spec(None, kind="mapping", default_factory=dict)
    eval_episode_steps: int = _int(1, 1000, hi=1_000_000)
    select_by: str = spec(None, kind="str", choices=SELECT_BY, default="return")
    select_reference: str | None = spec(None, kind="str", choices=SELECT_REFERENCES, optional=True,
                                        default=None)
    eval_scenarios: tuple = spec(None, kind="list", items=Spec(None, "str", choices=tuple(SCENARIO_TASKS)),
                                 default=DEFAULT_SCENARIOS)
    test_scenarios: tuple = spec(None, kind="list", items=Spec(None, "str", choices=tuple(SCENARIO_TASKS)),
                                 default=DEFAULT_SCENARIOS)
    checkpoint_freq: int = _int(0, 200_000, hi=MAX_TIMESTEPS)
    torch_threads: int = _int(1, 1, hi=MAX_THREADS)
    progress_bar: bool = _flag(True)
    verbose: int = _int(0, 1, hi=2)


@dataclass(frozen=True)
class PPOSettings(CommonSettings):
    """PPO's keys (stable-baselines3 names and defaults of this package)."""

    n_steps: int = _int(1, 256, hi=MAX_ROLLOUT)
    batch_size: int = _int(2, 256, hi=MAX_ROLLOUT)
    n_epochs: int = _int(1, 10, hi=1000)
    gae_lambda: float = _num(0.95, lo=0.0, hi=1.0)
    clip_range: float = _num(0.2, lo=0.0, lo_open=True)
    ent_coef: float = _num(0.0, lo=0.0)
    vf_coef: float = _num(0.5, lo=0.0)
    max_grad_norm: float = _num(0.5, lo=0.0, lo_open=True)
    target_kl: float | None = _num(None, lo=0.0, lo_open=True, optional=True)


@dataclass(frozen=True)
class RecurrentPPOSettings(PPOSettings):
    """RecurrentPPO's keys: PPO's and the LSTM's."""

    lstm_hidden_size: int = _int(1, 64, hi=MAX_LAYER)
    n_lstm_layers: int = _int(1, 1, hi=MAX_LAYERS)
    shared_lstm: bool = _flag(False)
    enable_critic_lstm: bool = _flag(True)


@dataclass(frozen=True)
class SACSettings(CommonSettings):
    """SAC's keys (SB3's defaults for the network: [256, 256] ReLU, log std -3)."""

    n_envs: int = _int(1, 1, hi=MAX_ENVS)
    net_arch: Any = spec(None, kind="any", default_factory=lambda: [256, 256])
    activation_fn: str = spec(None, kind="str", choices=ACTIVATIONS, default="relu")
    log_std_init: float = _num(-3.0, lo=-20.0, hi=5.0)
    buffer_size: int = _int(1, 1_000_000, hi=MAX_ROLLOUT)
    learning_starts: int = _int(0, 10_000, hi=MAX_TIMESTEPS)
    batch_size: int = _int(1, 256, hi=MAX_ROLLOUT)
    tau: float = _num(0.005, lo=0.0, hi=1.0, lo_open=True)
    train_freq: int = _int(1, 1, hi=MAX_TIMESTEPS)
    gradient_steps: int = _int(-1, 1, hi=100_000)
    ent_coef: float | str = _num("auto", lo=0.0, lo_open=True, choices=("auto",))
    target_entropy: float | str = _num("auto", choices=("auto",))
    save_replay_buffer: bool = _flag(True)


#: the settings class of each algorithm
SETTINGS: dict[str, type] = {"ppo": PPOSettings, "recurrent_ppo": RecurrentPPOSettings,
                             "sac": SACSettings}


def keys_of(algo: str) -> list[str]:
    """The keys of a configuration of ``algo``."""
    return [f.name for f in dataclasses.fields(SETTINGS[algo])]


def _layers(v: Any, where: str) -> list[int]:
    if not isinstance(v, (list, tuple)) or not v or len(v) > MAX_LAYERS or not all(
            isinstance(n, (int, np.integer)) and not isinstance(n, bool) and 1 <= n <= MAX_LAYER
            for n in v):
        raise ConfigError(f"{where}: must be a list of 1 to {MAX_LAYERS} layer sizes (integers "
                          f">= 1 and <= {MAX_LAYER}), got {v!r}")
    return [int(n) for n in v]


#: the keys of one part of a ``mixture``
MIXTURE_KEYS = ("preset", "n_envs", "env_kwargs", "max_episode_steps")


def _mixture(v: Any, n_envs: int, source: str) -> list[dict[str, Any]]:
    """A checked ``mixture``: a list of parts ``{preset, n_envs, env_kwargs?,
    max_episode_steps?}`` (a preset of :data:`dss14_env.envs.presets.PRESETS`) whose
    sub-environment counts sum to ``n_envs``; empty: no mixture.
    """
    from dss14_env.envs.presets import PRESETS

    where = f"{source}: field 'mixture'"
    if v is None or v == []:
        return []
    if not isinstance(v, (list, tuple)) or len(v) > len(PRESETS) * 4:
        raise ConfigError(f"{where}: must be a list of parts {{preset, n_envs, env_kwargs, "
                          f"max_episode_steps}}, got {v!r}"[:300])
    parts = []
    for k, part in enumerate(v):
        at = f"{source}: field 'mixture[{k}]'"
        if not isinstance(part, Mapping) or set(part) - set(MIXTURE_KEYS) or "preset" not in part:
            raise ConfigError(f"{at}: must be a mapping with 'preset' and 'n_envs' (keys "
                              f"{', '.join(MIXTURE_KEYS)}), got {part!r}"[:300])
        if part["preset"] not in PRESETS:
            raise ConfigError(f"{at}: 'preset' must be one of {', '.join(PRESETS)}, got "
                              f"{part['preset']!r}")
        n = part.get("n_envs")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_ENVS:
            raise ConfigError(f"{at}: 'n_envs' must be an integer 1-{MAX_ENVS}, got {n!r}")
        steps = part.get("max_episode_steps")
        if steps is not None and (isinstance(steps, bool) or not isinstance(steps, (int, np.integer))
                                  or not 1 <= steps <= 1_000_000):
            raise ConfigError(f"{at}: 'max_episode_steps' must be an integer 1-1000000, got {steps!r}")
        kw = part.get("env_kwargs", {})
        if not isinstance(kw, Mapping) or not all(isinstance(x, str) for x in kw):
            raise ConfigError(f"{at}: 'env_kwargs' must be a mapping of environment keys, got {kw!r}"[:300])
        parts.append({"preset": str(part["preset"]), "n_envs": int(n), "env_kwargs": dict(kw),
                      "max_episode_steps": None if steps is None else int(steps)})
    total = sum(p["n_envs"] for p in parts)
    if total != n_envs:
        raise ConfigError(f"{where}: the parts' n_envs must sum to n_envs = {n_envs}, got {total}")
    return parts


def _net_arch(v: Any, algo: str, source: str) -> Any:
    where = f"{source}: field 'net_arch'"
    if isinstance(v, Mapping):
        want = {"pi", "qf"} if algo == "sac" else {"pi", "vf"}
        if set(v) != want:
            raise ConfigError(f"{where}: a mapping must have exactly the keys "
                              f"{' and '.join(sorted(want))} for {algo}, got {v!r}")
        return {k: _layers(v[k], f"{where[:-1]}.{k}'") for k in sorted(v)}
    return _layers(v, where)


def _plain(o: Any) -> Any:
    return o.item() if hasattr(o, "item") else str(o)


# ------------------------------------------------------------------------------ sweeps
@dataclass(frozen=True)
class SweepPoint:
    """One point of a sweep's grid.

    :param label: the point's folder name (``learning_rate=0.0001,log_std_init=-2.5``, or
        ``point_NN`` when the readable labels are too long or clash)
    :param values: swept key -> this point's value (plain YAML types)
    :param config: the configuration of the point (no ``sweep``)
    """

    label: str
    values: dict[str, Any]
    config: TrainConfig


def _label_value(v: Any) -> str:
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, float):
        return repr(v)
    text = v if isinstance(v, str) else json.dumps(v, separators=(",", ":"), sort_keys=True)
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_") or "_"


def point_labels(points: list[dict[str, Any]]) -> list[str]:
    """Folder names of sweep points: ``key=value`` joined by commas (floats in their shortest
    round-trip form, other characters than letters, digits and ``.+-`` replaced by ``_``), or
    ``point_00``, ``point_01``, ... for all points when one such label is longer than
    :data:`MAX_LABEL_CHARS` or two of them are equal.

    >>> point_labels([{"learning_rate": 1e-4, "net_arch": [64, 64]},
    ...               {"learning_rate": 3e-4, "net_arch": [64, 64]}])
    ['learning_rate=0.0001,net_arch=64_64', 'learning_rate=0.0003,net_arch=64_64']
    """
    labels = [",".join(f"{k}={_label_value(v)}" for k, v in p.items()) for p in points]
    if len(set(labels)) == len(labels) and all(len(x) <= MAX_LABEL_CHARS for x in labels):
        return labels
    width = max(2, len(str(len(points) - 1)))
    return [f"point_{i:0{width}d}" for i in range(len(points))]


def _set_dotted(values: dict[str, Any], key: str, v: Any, where: str) -> None:
    head, *rest = key.split(".")
    if not rest:
        values[head] = v
        return
    inner = values.get(head)
    if inner is None:
        inner = {}
    if not isinstance(inner, Mapping):
        raise ConfigError(f"{where}: '{head}' is not a mapping in this configuration, got {inner!r}")
    inner = dict(inner)
    _set_dotted(inner, ".".join(rest), v, where)
    values[head] = inner


def _sweep_value_spec(key: str, algo: str, source: str) -> Spec | None:
    """The spec of a swept key (None: any value, checked with the whole point)."""
    where = f"{source}: field 'sweep.{key}'"
    head, *rest = key.split(".")
    if not key or not all(key.split(".")):
        raise ConfigError(f"{source}: field 'sweep': keys must be configuration keys, got {key!r}")
    if head in NOT_SWEPT:
        why = ("the seeds of a sweep are --train-seeds" if head == "seed" else
               "a sweep cannot be swept" if head == "sweep" else "a sweep keeps one algorithm")
        raise ConfigError(f"{where}: cannot be swept ({why})")
    fields = {f.name: f for f in dataclasses.fields(SETTINGS[algo])}
    if head not in fields:
        owners = [a for a in ALGOS if head in keys_of(a)]
        if owners:
            raise ConfigError(f"{where}: is not a setting of algo {algo!r} (it belongs to "
                              f"{', '.join(owners)})")
        near = difflib.get_close_matches(head, list(fields), n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ConfigError(f"{where}: unknown key {head!r}{hint}")
    s = field_spec(fields[head])
    if rest:
        if s.kind != "mapping":
            raise ConfigError(f"{where}: a dotted key must name an entry of a mapping key "
                              f"(env_kwargs, eval_env_kwargs), {head!r} is not one")
        return None
    return s if s.kind != "any" else None


def check_sweep(sweep: Any, base: Mapping[str, Any], source: str) -> dict[str, list]:
    """A sweep specification checked against the configuration it varies.

    :param sweep: ``{key: [value, ...]}`` (a dotted key sets one entry of a mapping key)
    :param base: the configuration's own values (validated)
    :param source: the file, for messages
    :return: the specification with every value normalised (``"1e-4"`` -> ``0.0001``)
    :raises ConfigError: not a non-empty mapping of keys to non-empty lists of distinct values;
        a key that is unknown, of another algorithm, ``seed``, ``algo`` or ``sweep``, or given
        twice (``env_kwargs`` and ``env_kwargs.x``); a value that is bad for its key; a point
        that is not a valid configuration; more than :data:`MAX_SWEEP_POINTS` points
    """
    if not isinstance(sweep, Mapping) or not sweep:
        raise ConfigError(f"{source}: field 'sweep': must be a mapping of configuration keys to "
                          f"lists of values, got {sweep!r}")
    out: dict[str, list] = {}
    for key, values in sweep.items():
        if not isinstance(key, str):
            raise ConfigError(f"{source}: field 'sweep': keys must be configuration keys, got "
                              f"{key!r}")
        s = _sweep_value_spec(key, base["algo"], source)
        where = f"{source}: field 'sweep.{key}'"
        if not isinstance(values, (list, tuple)) or not values:
            raise ConfigError(f"{where}: must be a non-empty list of values, got {values!r}")
        norm = [check_value(s, v, where) if s is not None else v for v in values]
        norm = json.loads(json.dumps(norm, default=_plain))
        dumped = [json.dumps(v, sort_keys=True) for v in norm]
        if len(set(dumped)) != len(dumped):
            raise ConfigError(f"{where}: values must be distinct, got {values!r}")
        for other in out:
            if key.startswith(other + ".") or other.startswith(key + "."):
                raise ConfigError(f"{where}: overlaps 'sweep.{other}' (sweep a mapping or its "
                                  f"entries, not both)")
        out[key] = norm
    n = int(np.prod([len(v) for v in out.values()]))
    if n > MAX_SWEEP_POINTS:
        raise ConfigError(f"{source}: field 'sweep': must have at most {MAX_SWEEP_POINTS} points, "
                          f"got a grid of {n}")
    return out


def sweep_grid(sweep: Mapping[str, list]) -> list[dict[str, Any]]:
    """Every combination of a sweep's values (the Cartesian product, the last key fastest).

    >>> sweep_grid({"learning_rate": [1e-4, 3e-4], "log_std_init": [-2.5, -1.5]})
    ... # doctest: +NORMALIZE_WHITESPACE
    [{'learning_rate': 0.0001, 'log_std_init': -2.5}, {'learning_rate': 0.0001, 'log_std_init': -1.5},
     {'learning_rate': 0.0003, 'log_std_init': -2.5}, {'learning_rate': 0.0003, 'log_std_init': -1.5}]
    """
    keys = list(sweep)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*sweep.values())]


def _points(base: Mapping[str, Any], sweep: Mapping[str, list], source: str) -> list[SweepPoint]:
    grid = sweep_grid(sweep)
    out = []
    for label, point in zip(point_labels(grid), grid, strict=True):
        values = json.loads(json.dumps(dict(base)))
        for key, v in point.items():
            _set_dotted(values, key, v, f"{source}: field 'sweep.{key}'")
        out.append(SweepPoint(label, point, TrainConfig(values, f"{source} [sweep point {label}]")))
    return out


class TrainConfig:
    """Everything one training run needs (see the module doc and ``docs/rl.md``).

    Read the values as attributes (``cfg.n_steps``); build with :meth:`from_dict` or
    :func:`load_config`; change with :meth:`replace` (validated again).

    :param values: key -> value; missing keys take the defaults of ``values["algo"]``; an
        optional ``sweep`` makes it a sweep (:meth:`points`)
    :param source: file the values came from (error messages only)
    """

    __slots__ = ("_sweep", "_values", "source")

    def __init__(self, values: Mapping[str, Any] | None = None, source: str = "<dict>") -> None:
        values = dict(values or {})
        has_sweep = "sweep" in values
        sweep = values.pop("sweep", None)
        object.__setattr__(self, "source", source)
        algo = values.get("algo", "ppo")
        if algo not in ALGOS:
            raise ConfigError(f"{source}: field 'algo': must be one of {list(ALGOS)}, got {algo!r}")
        mine = set(keys_of(algo))
        for key in values:
            owners = [a for a in ALGOS if key in keys_of(a)]
            if key not in mine and owners:
                raise ConfigError(f"{source}: field '{key}': is not a setting of algo {algo!r} "
                                  f"(it belongs to {', '.join(owners)})")
        settings = load_section(SETTINGS[algo], values, source)
        out = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
        out["net_arch"] = _net_arch(out["net_arch"], algo, source)
        out["mixture"] = _mixture(out["mixture"], out["n_envs"], source)
        out["eval_seeds"] = list(out["eval_seeds"])
        out["test_scenarios"] = _test_scenarios(out["test_scenarios"], source)
        out["eval_scenarios"] = _test_scenarios(out["eval_scenarios"], source, "eval_scenarios")
        if out["select_reference"] is not None and out["select_by"] == "return":
            raise ConfigError(f"{source}: field 'select_reference': needs select_by three_sigma, "
                              f"pointing or general (figures to compare), got select_by return")
        out = json.loads(json.dumps(out, default=_plain))  # plain YAML types
        if algo in ("ppo", "recurrent_ppo"):
            rollout = out["n_steps"] * out["n_envs"]
            if rollout > MAX_ROLLOUT:
                raise ConfigError(f"{source}: field 'n_steps': n_steps * n_envs must be <= "
                                  f"{MAX_ROLLOUT} (the rollout buffer), got {rollout}")
            if out["batch_size"] > rollout or rollout % out["batch_size"]:
                raise ConfigError(f"{source}: field 'batch_size': must divide n_steps * n_envs = "
                                  f"{rollout}, got {out['batch_size']}")
        object.__setattr__(self, "_values", out)
        object.__setattr__(self, "_sweep", check_sweep(sweep, out, source) if has_sweep else {})
        if self._sweep:
            _points(out, self._sweep, source)  # every point is a valid configuration

    # -- access -----------------------------------------------------------------------------
    def __getattr__(self, name: str) -> Any:
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no key {name!r}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("TrainConfig is immutable; use replace()")

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, TrainConfig) and self._values == other._values
                and self._sweep == other._sweep)

    def __hash__(self) -> int:
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def __repr__(self) -> str:
        return f"TrainConfig({self.to_dict()!r})"

    def __reduce__(self) -> Any:  # SubprocVecEnv workers and Ray tasks receive the config
        return (TrainConfig, (self.to_dict(), self.source))

    @property
    def sweep(self) -> dict[str, list]:
        """The sweep specification (swept key -> its values); empty for a single configuration."""
        return json.loads(json.dumps(self._sweep))

    def points(self) -> list[SweepPoint]:
        """The points of the sweep's grid (empty without a sweep), in grid order
        (:func:`sweep_grid`), each with its label, values and configuration.
        """
        return _points(self._values, self._sweep, self.source) if self._sweep else []

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> TrainConfig:
        """A validated config from a mapping; missing keys take their defaults.

        :raises ValueError: unknown key or bad value, naming the key and ``source``
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: top level must be a mapping of fields, got "
                              f"{type(data).__name__}")
        return cls(data, source)

    def replace(self, source: str | None = None, **changes: Any) -> TrainConfig:
        """Copy with some values changed (validated again), e.g. ``cfg.replace(seed=3)``.

        Changing ``algo`` keeps the common keys and drops the old algorithm's.  The sweep is
        kept (its points validated again with the new values); ``sweep={}`` drops it.
        """
        values = dict(self._values)
        sweep = changes.pop("sweep", self._sweep)
        if "algo" in changes and changes["algo"] != values["algo"]:
            common = {f.name for f in dataclasses.fields(CommonSettings)}
            new_defaults = {f.name for f in dataclasses.fields(SETTINGS.get(changes["algo"],
                                                                            PPOSettings))
                            if f.name in common and
                            f.default != getattr(CommonSettings, f.name, f.default)}
            values = {k: v for k, v in values.items() if k in common and k not in new_defaults}
        values.update(changes)
        if sweep:
            values["sweep"] = sweep
        return TrainConfig(values, source or self.source)

    def to_dict(self) -> dict[str, Any]:
        """Plain-YAML mapping of every key, and ``sweep`` last when there is one (loads back
        with :meth:`from_dict`).
        """
        out = {**self._values, **({"sweep": self._sweep} if self._sweep else {})}
        return json.loads(json.dumps(out, default=_plain))


#: the name of the earlier PPO-only configuration class
PPOConfig = TrainConfig


# ------------------------------------------------------------------------------ files
def default_config_path(name: str = "ppo.yaml") -> Path:
    """Path of a training configuration shipped in the ``configs`` package.

    :param name: file name, default ``"ppo.yaml"`` (``"ppo_smoke.yaml"``: Pendulum-v1 smoke run)
    """
    return shipped_config_path(name)


def check_training_config_name(path: str | Path) -> None:
    """Refuse, in one line, a ``--config`` that is neither a file nor a shipped configuration
    (a shipped model, env, wind or controllers configuration is refused as such when read:
    :func:`~dss14_env.core.schema.check_config_kind`).

    :raises ConfigError: listing the shipped training configurations
    """
    p = Path(path)
    if p.exists():
        return
    stem = p.name[:-5] if p.name.endswith(".yaml") else p.name
    training = shipped_training_configs()
    if stem in training and (len(p.parts) <= 1 or p.parts[0] == "configs"):
        return
    if stem in shipped_configs():  # a shipped configuration of another kind: read_config names it
        return
    names = ", ".join(training)
    raise ConfigError(f"{path}: configuration file not found (neither a file nor a shipped training "
                      f"configuration: {names})")


def is_known_env_module(name: Any) -> bool:
    """Whether ``name`` is one of :data:`KNOWN_ENV_MODULES`, the only modules a configuration
    file may name.
    """
    return isinstance(name, str) and name in KNOWN_ENV_MODULES


def _import_fields(values: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The fields of a configuration that could make gymnasium import a module."""
    out = [("env_id", values.get("env_id"))]
    for key in ("env_kwargs", "eval_env_kwargs"):
        inner = values.get(key)
        if isinstance(inner, Mapping) and "base_id" in inner:
            out.append((f"{key}.base_id", inner["base_id"]))
    return out


def check_file_imports(cfg: TrainConfig, env_module: str | None = None) -> TrainConfig:
    """Refuse a configuration read from a file that would make the tools import a module.

    A file names environments only by registered ids: ``env_module`` may be null or one of
    the fixed table :data:`KNOWN_ENV_MODULES`, and no id may take gymnasium's ``module:id`` form (which
    imports ``module``).  Importing a module of the user's, which runs its code, is the user's
    explicit opt-in (``env_module`` here; ``dss14 train --env-module``), never a field of a file.
    Every point of a sweep is checked too.

    :param cfg: the configuration as read from its file
    :param env_module: the module the user allows the file to name (the opt-in), or None
    :return: ``cfg``
    :raises ConfigError: naming the file and the field
    """
    for c in [cfg, *(p.config for p in cfg.points())]:
        values = c.to_dict()
        mod = values.get("env_module")
        if mod is not None and not is_known_env_module(mod) and mod != env_module:
            raise ConfigError(
                f"{c.source}: field 'env_module': {mod!r} names a module to import, and importing "
                f"runs its code: a file may name only null or one of "
                f"{', '.join(KNOWN_ENV_MODULES)}; if you trust it, pass --env-module {mod} (dss14 train) or "
                f"env_module={mod!r} (load_config, load_policy)")
        for key, v in _import_fields(values):
            if isinstance(v, str) and ":" in v:
                raise ConfigError(
                    f"{c.source}: field '{key}': {v!r} is gymnasium's 'module:id' form, which "
                    f"imports the module: a file may name only registered environment ids; "
                    f"register yours by importing its module (dss14 train --env-module MODULE)")
    return cfg


def load_config(path: str | Path | None = None, env_module: str | None = None) -> TrainConfig:
    """Read and validate a training YAML file.

    Nothing in the file can make the tools import a module (:func:`check_file_imports`).

    :param path: the file or a shipped config's name, default None: the shipped
        ``configs/ppo.yaml``
    :param env_module: a module of the user's that the file may name in ``env_module`` (the
        explicit opt-in: importing it runs its code), default None: only this package's own
    :raises ConfigError: missing/unreadable file, YAML error, unknown key or bad value, a module
        to import (one line naming the file and the field)
    """
    if path is not None:
        check_training_config_name(path)
    data, source = read_config(path if path is not None else "ppo", kind="training")
    return check_file_imports(TrainConfig.from_dict(data, source=source), env_module)


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


__all__ = ["ACTIVATIONS", "ALGOS", "MAX_LABEL_CHARS", "MAX_SWEEP_POINTS", "NOT_SWEPT", "SELECT_BY",
           "CommonSettings", "MAX_ENVS", "MAX_LAYER", "MAX_LAYERS", "MAX_ROLLOUT", "MAX_SEED",
           "MAX_THREADS", "MAX_TIMESTEPS", "KNOWN_ENV_MODULES", "PPOConfig", "PPOSettings",
           "RecurrentPPOSettings", "SACSettings",
           "SETTINGS", "SweepPoint", "TrainConfig", "VEC_ENVS", "as_config", "check_file_imports",
           "check_sweep", "is_known_env_module",
           "default_config_path", "keys_of", "load_config", "point_labels", "shipped_config_path",
           "check_training_config_name", "shipped_training_configs", "shipped_training_configs_by_algo",
           "sweep_grid"]
