"""The configuration layer: one schema mechanism and one loader for every configuration.

Every configuration of the project -- the model (``configs/model.yaml``), the wind loads
(``wind.yaml``), the controllers (``controllers.yaml``), the environments (``env.yaml``) and the
learning agents (``ppo*.yaml``) -- is a frozen dataclass whose fields carry a :class:`Spec`
(made with :func:`spec`): unit, range, choices, integer, optional.  One function,
:func:`load_section`, checks a mapping against such a dataclass and builds it; one function,
:func:`read_config`, reads a YAML file (a path, or the name of a shipped file such as
``"ppo_plain"``).  Every problem is a :class:`ConfigError` with one message style::

    <file>: field '<name>': must be <what>, got <value>

YAML syntax errors are reported the same way (``<file>: not valid YAML (line L, column C):
...``); numbers are YAML 1.2's (``1e-3`` and ``1.29e6``, which plain YAML 1.1 reads as
strings, are numbers; ``010`` is ten, and ``1:30`` and ``1_000``, which YAML 1.1 reads as 90 and
1000, are strings).  A number in quotes
(``'256'``) is a string, and a string is never taken for a number: a field that wants a
number refuses it like any other wrong type.  A file is at most :data:`MAX_CONFIG_BYTES`
long and expands to at most :data:`MAX_YAML_NODES` values (aliases that repeat aliases, a
"billion laughs", and an alias that contains itself are refused at once, naming the file).

Two kinds of leaves:

* *documented* leaves (model, wind, controllers): ``{value, unit, source[, range][, note]}`` in
  the source's own units (the report's cm^3, kPa, in^3, ...); the value is converted to SI
  (:mod:`dss14_env.core.units`; its unit must be of the spec's SI family), the optional
  ``range`` is checked and kept, and the whole leaf is recorded as a :class:`Param` in the
  configuration's registry;
* *plain* leaves (environment, agents): the value itself, in the unit the spec (and the key's
  name) states.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Demo:
...     dt: float = spec("s", lo=0.0, lo_open=True, hi=0.1, default=0.02)
...     speed: float | str = spec("km/h", lo=0.0, choices=("random",), default=50.0)
>>> load_section(Demo, {"dt": 1e-3, "speed": "random"}, "demo.yaml")
Demo(dt=0.001, speed='random')
>>> load_section(Demo, {"dt": "1e-3"}, "demo.yaml")
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: demo.yaml: field 'dt': must be a number > 0 and <= 0.1 (s), got '1e-3'
>>> load_section(Demo, {"dt": 0.5}, "demo.yaml")
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: demo.yaml: field 'dt': must be a number > 0 and <= 0.1 (s), got 0.5
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dss14_env.core.files import read_text
from dss14_env.core.units import AXES, UNITS, si_unit, to_si

#: the kinds of value a field can hold
KINDS = ("number", "integer", "bool", "str", "list", "pair", "mapping", "any")
#: longest configuration file read, bytes
MAX_CONFIG_BYTES = 1 << 20
#: most values (scalars, lists, mappings) a configuration file may expand to, aliases expanded
MAX_YAML_NODES = 100_000
#: largest integer an integer field without an upper bound of its own takes (numpy's int64)
MAX_INTEGER = 2**63 - 1


class ConfigError(ValueError):
    """A configuration value is missing, malformed or out of range (one line naming the file
    and the field).
    """

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


@dataclass(frozen=True)
class Param:
    """One documented parameter as read from its file, converted to SI."""

    name: str
    value: Any  # float, or tuple of floats for vector parameters
    unit: str  # SI unit
    source: str
    range: tuple[float, float] | None = None
    note: str = ""


@dataclass(frozen=True)
class Spec:
    """The schema of one configuration field.

    :param unit: the field's unit (SI family for documented leaves; the unit of the key for
        plain leaves), ``"1"`` for dimensionless numbers, None for non-quantities
    :param kind: one of :data:`KINDS`
    :param lo: lower bound of a number (of each element for lists and pairs)
    :param hi: upper bound
    :param lo_open: the lower bound is excluded
    :param hi_open: the upper bound is excluded
    :param choices: allowed strings (``kind="str"``), or strings allowed besides a number
        (e.g. ``"random"``)
    :param optional: ``null`` (None) is allowed
    :param items: spec of the elements of a ``list`` or ``pair`` (default: numbers with the
        bounds above)
    :param min_length: least number of elements of a list
    :param axis: a per-axis mapping ``{az: .., el: ..}`` of leaves (documented files)
    """

    unit: str | None = "1"
    kind: str = "number"
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] = ()
    optional: bool = False
    items: Spec | None = None
    min_length: int = 1
    axis: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Spec kind must be one of {KINDS}, got {self.kind!r}")

    def describe(self) -> str:
        """What a valid value is, for messages (``a number > 0 and <= 0.1 (s)``)."""
        if self.kind == "bool":
            what = "true or false"
        elif self.kind == "str":
            what = f"one of {list(self.choices)}" if self.choices else "a string"
        elif self.kind == "mapping":
            what = "a mapping"
        elif self.kind == "any":
            what = "a value"
        elif self.kind in ("list", "pair"):
            inner = (self.items or dataclasses.replace(self, kind="number", choices=(),
                                                       optional=False)).describe()
            what = ("a pair [low, high] of " if self.kind == "pair" else "a list of ") + \
                inner.removeprefix("a ").removeprefix("an ").replace("number", "numbers", 1)
        else:
            what = "an integer" if self.kind == "integer" else "a number"
            bounds = []
            fmt = (lambda x: f"{int(x)}") if self.kind == "integer" else (lambda x: f"{x:g}")
            if self.lo is not None:
                bounds.append(f"{'>' if self.lo_open else '>='} {fmt(self.lo)}")
            if self.hi is not None:
                bounds.append(f"{'<' if self.hi_open else '<='} {fmt(self.hi)}")
            if bounds:
                what += " " + " and ".join(bounds)
            if self.unit not in (None, "1"):
                what += f" ({self.unit})"
            if self.choices:
                what += " or one of " + ", ".join(repr(c) for c in self.choices)
        if self.optional:
            what += " or null"
        return what


def spec(unit: str | None = "1", *, kind: str = "number", lo: float | None = None,
         hi: float | None = None, lo_open: bool = False, hi_open: bool = False,
         choices: tuple[str, ...] | list[str] = (), optional: bool = False,
         items: Spec | None = None, min_length: int = 1, axis: bool = False,
         default: Any = dataclasses.MISSING, default_factory: Any = dataclasses.MISSING) -> Any:
    """A dataclass field with its :class:`Spec` (see the module docstring).

    ``default`` / ``default_factory`` as for :func:`dataclasses.field`; a field without either
    is required.
    """
    s = Spec(unit, kind, lo, hi, lo_open, hi_open, tuple(choices), optional, items, min_length,
             axis)
    kw: dict[str, Any] = {"metadata": {"spec": s}}
    if default is not dataclasses.MISSING:
        kw["default"] = default
    if default_factory is not dataclasses.MISSING:
        kw["default_factory"] = default_factory
    return field(**kw)


def field_spec(f: dataclasses.Field) -> Spec | None:
    """The :class:`Spec` of a dataclass field made with :func:`spec` (None otherwise)."""
    return f.metadata.get("spec")


# ------------------------------------------------------------------------------ values
def _is_number(v: Any) -> bool:
    return (isinstance(v, (int, float, np.integer, np.floating))
            and not isinstance(v, (bool, np.bool_)))


def _as_number(v: Any) -> Any:
    """A numpy number as a Python float/int; anything else (a string too) unchanged."""
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


def check_value(s: Spec, value: Any, where: str) -> Any:
    """``value`` checked against ``s`` (plain leaf); the normalised value.

    :param where: ``"<file>: field '<name>'"`` for the message
    :raises ConfigError: ``"<where>: must be <what>, got <value>"``
    """
    if value is None:
        if s.optional:
            return None
        raise _bad(s, value, where)
    return _CHECKS[s.kind](s, value, where)


def _bad(s: Spec, value: Any, where: str) -> ConfigError:
    return ConfigError(f"{where}: must be {s.describe()}, got {value!r}")


def _check_any(s: Spec, value: Any, where: str) -> Any:
    return value


def _check_bool(s: Spec, value: Any, where: str) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise _bad(s, value, where)


def _check_str(s: Spec, value: Any, where: str) -> str:
    if isinstance(value, str) and (not s.choices or value in s.choices):
        return value
    raise _bad(s, value, where)


def _check_mapping(s: Spec, value: Any, where: str) -> dict:
    if isinstance(value, Mapping) and all(isinstance(key, str) for key in value):
        return dict(value)
    raise _bad(s, value, where)


def _check_sequence(s: Spec, value: Any, where: str) -> tuple:
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (list, tuple, np.ndarray)):
        raise _bad(s, value, where)
    if (s.kind == "pair" and len(value) != 2) or (s.kind == "list" and len(value) < s.min_length):
        raise _bad(s, value, where)
    inner = s.items or dataclasses.replace(s, kind="number", choices=(), optional=False)
    out = tuple(check_value(inner, v, where) for v in value)
    if s.kind == "pair" and _is_number(out[0]) and out[0] > out[1]:
        raise ConfigError(f"{where}: must be a pair with low <= high, got {value!r}")
    return out


def _check_number(s: Spec, value: Any, where: str) -> float | int | str:
    if isinstance(value, str) and value in s.choices:
        return value
    v = _as_number(value)
    if not _is_number(v) or not math.isfinite(float(v)):
        raise _bad(s, value, where)
    if s.kind == "integer":
        if not float(v).is_integer():
            raise _bad(s, value, where)
        v = int(v)
        if s.hi is None and abs(v) > MAX_INTEGER:  # an integer without its own bound
            raise _bad(dataclasses.replace(s, hi=MAX_INTEGER), value, where)
    else:
        v = float(v)
    if s.lo is not None and (v <= s.lo if s.lo_open else v < s.lo):
        raise _bad(s, value, where)
    if s.hi is not None and (v >= s.hi if s.hi_open else v > s.hi):
        raise _bad(s, value, where)
    return v


_CHECKS = {"any": _check_any, "bool": _check_bool, "str": _check_str, "mapping": _check_mapping,
           "list": _check_sequence, "pair": _check_sequence, "number": _check_number,
           "integer": _check_number}


def documented_param(s: Spec, raw: Any, name: str, source: str) -> Param:
    """A documented leaf ``{value, unit, source[, range][, note]}`` checked against ``s`` and
    converted to SI.

    The leaf's unit must convert to the spec's SI unit (:data:`dss14_env.core.units.UNITS`);
    the bounds of the spec apply to the value in the file's units when the spec is
    dimensionless, otherwise to the SI value; a given ``range`` must hold the value.
    Non-numeric specs (strings, booleans) take ``{value, source}``.
    """
    where = f"{source}: field '{name}'"
    if not isinstance(raw, Mapping) or "value" not in raw or "source" not in raw:
        need = "'value', 'unit' and 'source'" if s.unit is not None else "'value' and 'source'"
        raise ConfigError(f"{where}: must be a mapping with {need}, got {raw!r}")
    extra = {str(k) for k in raw} - {"value", "unit", "source", "range", "note"}
    if extra:
        raise ConfigError(f"{where}: unknown key(s) {sorted(extra)} (allowed: value, unit, source, "
                          f"range, note)")
    if s.kind in ("str", "bool", "mapping", "any"):
        return Param(name, check_value(s, raw["value"], where), s.unit or "", str(raw["source"]),
                     None, str(raw.get("note", "")))
    unit = raw.get("unit")
    if not isinstance(unit, str) or unit not in UNITS:
        raise ConfigError(f"{where}: unit must be one of the known units, got {unit!r}")
    if s.unit is not None and si_unit(unit) != s.unit:
        raise ConfigError(f"{where}: unit must be a {s.unit} quantity, got {unit!r}")

    def convert(v: Any) -> Any:
        if isinstance(v, tuple):
            return tuple(convert(x) for x in v)
        return v if s.kind == "integer" else to_si(v, unit)

    si_spec = dataclasses.replace(s, unit=si_unit(unit))
    value = convert(check_value(dataclasses.replace(s, lo=None, hi=None), raw["value"], where))
    check_value(si_spec, value if not isinstance(value, tuple) else list(value), where)
    rng = raw.get("range")
    rng_si = None
    if rng is not None:
        lo, hi = check_value(Spec(unit, "pair"), rng, f"{where} (range)")
        rng_si = (convert(lo), convert(hi))
        rel = 1e-9 * max(abs(rng_si[0]), abs(rng_si[1]))
        values = value if isinstance(value, tuple) else (value,)
        if not all(rng_si[0] - rel <= v <= rng_si[1] + rel for v in values):
            raise ConfigError(f"{where}: must lie in its range {list(rng)}, got {raw['value']!r}")
    return Param(name, value, si_unit(unit), str(raw["source"]), rng_si, str(raw.get("note", "")))


# ------------------------------------------------------------------------------ sections
def _unknown(keys: set[str], known: list[str], where: str) -> ConfigError:
    key = sorted(keys)[0]
    near = difflib.get_close_matches(key, known, n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return ConfigError(f"{where}: unknown field '{key}'{hint}; known: {', '.join(sorted(known))}")


def load_section(cls: type, section: Any, source: str, prefix: str = "", *,
                 documented: bool = False, registry: dict[str, Param] | None = None,
                 defaults: bool = True) -> Any:
    """Check a mapping against a dataclass of :func:`spec` fields and build the dataclass.

    :param cls: the dataclass
    :param section: the mapping (e.g. one section of a YAML file)
    :param source: the file (or ``"<dict>"``) for messages
    :param prefix: the section's name, prefixed to field names in messages and the registry
    :param documented: leaves are documented (``{value, unit, source, ...}``, converted to SI,
        recorded in ``registry``) instead of plain values
    :param registry: where documented parameters are recorded (``"block.field[.axis]"``)
    :param defaults: fields missing from ``section`` take their dataclass defaults (False:
        every field must be given)
    :raises ConfigError: unknown or missing fields, bad values
    """
    where = f"{source}: " + (f"section '{prefix}'" if prefix else "top level")
    if not isinstance(section, Mapping):
        raise ConfigError(f"{where}: must be a mapping, got {section!r}")
    fields = [f for f in dataclasses.fields(cls) if field_spec(f) is not None]
    known = [f.name for f in fields]
    extra = set(map(str, section)) - set(known)
    if extra:
        raise _unknown(extra, known, where)
    kwargs: dict[str, Any] = {}
    for f in fields:
        s = field_spec(f)
        name = f"{prefix}.{f.name}" if prefix else f.name
        has_default = (f.default is not dataclasses.MISSING
                       or f.default_factory is not dataclasses.MISSING)  # type: ignore[misc]
        if f.name not in section:
            if defaults and has_default:
                continue
            raise ConfigError(f"{source}: field '{name}': is missing")
        raw = section[f.name]
        if documented and s.axis:
            if not isinstance(raw, Mapping) or set(raw) != set(AXES):
                raise ConfigError(f"{source}: field '{name}': must be a mapping with exactly the "
                                  f"keys az and el, got {raw!r}")
            vals = {}
            for ax in AXES:
                p = documented_param(s, raw[ax], f"{name}.{ax}", source)
                if registry is not None:
                    registry[p.name] = p
                vals[ax] = p.value
            kwargs[f.name] = vals
        elif documented:
            p = documented_param(s, raw, name, source)
            if registry is not None:
                registry[p.name] = p
            kwargs[f.name] = p.value
        else:
            kwargs[f.name] = check_value(s, raw, f"{source}: field '{name}'")
    return cls(**kwargs)


def check_fields(obj: Any, source: str = "<config>", prefix: str = "") -> None:
    """Check every :func:`spec` field of a dataclass instance against its spec (plain values),
    e.g. after ``dataclasses.replace``.

    :raises ConfigError: the first bad field
    """
    for f in dataclasses.fields(obj):
        s = field_spec(f)
        if s is None:
            continue
        name = f"{prefix}.{f.name}" if prefix else f.name
        check_value(s, getattr(obj, f.name), f"{source}: field '{name}'")


# ------------------------------------------------------------------------------ files
def shipped_configs() -> list[str]:
    """Names of the configuration files shipped with the package (without ``.yaml``)."""
    root = resources.files("dss14_env.configs")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".yaml"))


def config_path(name_or_path: str | Path) -> Path:
    """The file of a configuration: an existing path, or the name of a shipped file.

    ``"ppo_plain"``, ``"ppo_plain.yaml"`` and ``"configs/ppo_plain.yaml"`` (from the source
    tree) all name the shipped file when no such path exists relative to the working folder.

    :raises ConfigError: neither a file nor a shipped name (the shipped names are listed)
    """
    p = Path(name_or_path)
    if p.is_file():
        return p
    stem = p.name[:-5] if p.name.endswith(".yaml") else p.name
    if len(p.parts) <= 1 or (len(p.parts) == 2 and p.parts[0] == "configs"):
        shipped = Path(str(resources.files("dss14_env.configs").joinpath(f"{stem}.yaml")))
        if shipped.is_file():
            return shipped
    if p.exists():
        raise ConfigError(f"{p}: is not a file")
    raise ConfigError(f"{p}: configuration file not found (neither a file nor a shipped "
                      f"configuration: {', '.join(shipped_configs())})")


def config_label(source: str | Path) -> str:
    """How a written file names a configuration: ``configs/<file>`` for a shipped one (wherever
    the package is installed, so that no machine's folder is recorded), else ``source`` as given.

    >>> config_label(config_path("env"))
    'configs/env.yaml'
    >>> config_label("my/own.yaml")
    'my/own.yaml'
    """
    p = Path(source)
    shipped = Path(str(resources.files("dss14_env.configs")))
    try:
        if p.parent.resolve() == shipped.resolve():
            return f"configs/{p.name}"
    except OSError:
        pass
    return str(source)


def default_config_path(name: str = "model.yaml") -> Path:
    """Path of a configuration file shipped in :mod:`dss14_env.configs`."""
    return Path(str(resources.files("dss14_env.configs").joinpath(name)))


class UniqueKeySafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a mapping with the same key twice (plain YAML keeps the
    last value silently, so a repeated field would override the first without a word).
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        """The mapping of ``node``; a repeated key raises a ``ConstructorError`` at its line."""
        seen: set = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                repeated = key in seen
            except TypeError:  # an unhashable key: SafeLoader's own error follows
                break
            if repeated:
                raise yaml.constructor.ConstructorError(
                    None, None, f"the key {key!r} appears twice in one mapping", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


#: YAML 1.2 core-schema integers and floats (https://yaml.org/spec/1.2.2/#1032-tag-resolution):
#: PyYAML resolves YAML 1.1's, where ``1:30`` is the integer 90 (base 60), ``010`` is 8 (octal),
#: ``1_000`` is 1000 and ``1e-3`` a string; here ``010`` is 10, ``1e-3`` a number, and ``1:30``
#: and ``1_000`` are strings (which a number field refuses)
_INT_TAG, _FLOAT_TAG = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_YAML12_INT = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_YAML12_FLOAT = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                           r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")


def _construct_yaml12_int(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    """The integer of a YAML 1.2 core-schema scalar (decimal, ``0o`` octal, ``0x`` hexadecimal)."""
    text = loader.construct_scalar(node)
    if text.startswith(("0o", "0x")):
        return int(text[2:], 8 if text[1] == "o" else 16)
    return int(text, 10)


UniqueKeySafeLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
UniqueKeySafeLoader.add_implicit_resolver(_INT_TAG, _YAML12_INT, list("-+0123456789"))
UniqueKeySafeLoader.add_implicit_resolver(_FLOAT_TAG, _YAML12_FLOAT, list("-+0123456789."))
UniqueKeySafeLoader.add_constructor(_INT_TAG, _construct_yaml12_int)


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [x for pair in node.value for x in pair]
    return list(node.value) if isinstance(node, yaml.SequenceNode) else []


def _expanded_size(node: yaml.Node, source: str, limit: int = MAX_YAML_NODES) -> int:
    """Number of values ``node`` stands for with every alias expanded, each node visited once
    (a bomb is measured in linear time).

    :raises ConfigError: more than ``limit``, or a node that contains itself (a recursive alias
        such as ``a: &a [*a]``, which would expand without end)
    """
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()  # the nodes whose children are being measured: the path here
    stack: list[tuple[yaml.Node, bool]] = [(node, False)]
    while stack:
        n, done = stack.pop()
        if done:
            open_nodes.discard(id(n))
            sizes[id(n)] = 1 + sum(sizes[id(k)] for k in _children(n))
            if sizes[id(n)] > limit:
                raise ConfigError(f"{source}: the YAML expands to more than {limit} values "
                                  f"(aliases that repeat aliases); refused")
            continue
        if id(n) in sizes:
            continue
        if id(n) in open_nodes:
            raise ConfigError(f"{source}: the YAML holds a value that contains itself (a recursive "
                              f"alias, line {n.start_mark.line + 1}); refused")
        open_nodes.add(id(n))
        stack.append((n, True))
        stack.extend((k, False) for k in _children(n) if id(k) not in sizes)
    return sizes[id(node)]


def load_yaml(text: str, source: str) -> Any:
    """The YAML document of ``text`` (:class:`UniqueKeySafeLoader`: YAML 1.2 numbers, each key
    once), its alias expansion bounded before any Python object is built: the one YAML reader
    of every file the tools read.

    :param source: the file, for messages
    :raises ConfigError: ``<source>: ...`` for a YAML error (with line and column), a recursive
        alias, an expansion past :data:`MAX_YAML_NODES` or nesting too deep
    """
    loader = None
    try:
        loader = UniqueKeySafeLoader(text)
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node, source)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise ConfigError(f"{source}: not valid YAML{at}: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{source}: the YAML is nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


#: the kinds of configuration file: the top-level fields only that kind has (what tells one
#: kind from another) and its shipped example
CONFIG_KINDS: dict[str, tuple[frozenset[str], str]] = {
    "model": (frozenset({"board", "hydraulics", "structure", "gearbox", "calibration", "reduction",
                         "position_loop", "recalibrate_wind"}), "configs/model.yaml"),
    "wind": (frozenset({"loads", "table4"}), "configs/wind.yaml"),
    "controllers": (frozenset({"design", "lqg", "mpc", "pointing"}), "configs/controllers.yaml"),
    "training": (frozenset({"algo", "env_id", "total_timesteps", "net_arch", "n_steps", "n_envs",
                            "learning_rate", "batch_size", "sweep", "mixture"}), "configs/ppo.yaml"),
    "environment": (frozenset({"dt", "scenario", "wind_speed_kmh", "wind_direction", "encoders",
                               "reward", "randomize_params", "params", "max_error_deg"}),
                    "configs/env.yaml"),
}


def check_config_kind(data: Mapping[str, Any], source: str, kind: str) -> None:
    """Refuse a configuration of another kind than ``kind`` (:data:`CONFIG_KINDS`): a file
    that has fields of another kind and none of its own.

    :raises ConfigError: one line naming the file, the kind it is and the kind wanted
    """
    keys = set(map(str, data))
    if keys & CONFIG_KINDS[kind][0]:
        return
    found = max(CONFIG_KINDS, key=lambda k: len(keys & CONFIG_KINDS[k][0]))
    if keys & CONFIG_KINDS[found][0]:
        shown = ", ".join(sorted(keys & CONFIG_KINDS[found][0])[:3])
        raise ConfigError(f"{source}: is {_a(found)} configuration (fields {shown}), not {_a(kind)} "
                          f"configuration; give {_a(kind)} configuration (like {CONFIG_KINDS[kind][1]})")


def _a(word: str) -> str:
    return f"{'an' if word[0] in 'aeiou' else 'a'} {word}"


#: parsed configuration texts a process keeps (:func:`read_config`), the least recently read
#: dropped first
PARSED_CONFIGS_KEPT = 32


@functools.lru_cache(maxsize=PARSED_CONFIGS_KEPT)
def parsed_config(text: str, source: str) -> Any:
    """:func:`load_yaml` of a configuration's text, parsed once per text and source (an edited
    file has another text and is parsed again).  The value is shared: :func:`read_config`
    hands out copies; ``parsed_config.cache_clear()`` forgets every text.
    """
    return load_yaml(text, source)


def read_config(name_or_path: str | Path, kind: str | None = None) -> tuple[dict[str, Any], str]:
    """Read a YAML configuration (a path or a shipped name, :func:`config_path`).

    Parsed by :func:`load_yaml` (``yaml.safe_load``'s loader: no Python objects are ever built
    from a file; YAML 1.2 numbers; a key repeated in one mapping, a recursive alias or an alias
    bomb refused).  The file is read every time; the same text is parsed once per process (the
    last :data:`PARSED_CONFIGS_KEPT` texts are kept) and each caller gets its own copy, so an
    edited file is read anew and a caller's changes reach no other caller.

    :param kind: the kind of configuration wanted (:data:`CONFIG_KINDS`; None: any): a file of
        another kind is refused as such (:func:`check_config_kind`)

    :return: ``(mapping, source)``: the top-level mapping (empty for an empty file) and the
        file's path as a string, for messages
    :raises ConfigError: missing file, YAML syntax error or a repeated key (with line and
        column), a top level that is not a mapping
    """
    path = config_path(name_or_path)
    source = str(path)
    try:
        text = read_text(path, MAX_CONFIG_BYTES, "configuration file")
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    except OSError as exc:
        raise ConfigError(f"{source}: cannot be read ({exc})") from None
    data = copy.deepcopy(parsed_config(text, source))
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: top level must be a mapping of fields, got "
                          f"{type(data).__name__}")
    if kind is not None:
        check_config_kind(data, source, kind)
    return dict(data), source
