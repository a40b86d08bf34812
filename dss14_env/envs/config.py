"""The configuration of the DSS14 environments: :class:`EnvConfig` on the one schema mechanism.

``configs/env.yaml`` holds every key with its default (flat keys, the unit in each key's name:
deg, mdeg, s, km/h).  :func:`load_env_config` reads it (:func:`dss14_env.core.schema.read_config`),
applies a user's file or mapping and keyword overrides, and checks every field against its
:func:`dss14_env.core.schema.spec` and the cross-field rules of :meth:`EnvConfig.checked`.
:meth:`EnvConfig.with_options` applies ``reset(options=...)``.  Every problem is a
:class:`dss14_env.core.schema.ConfigError` (a ``ValueError``) in the one message style
``<source>: field '<key>': must be ..., got ...``, where the source is the file, ``keyword
arguments`` or ``reset options``.

Bounds.  Besides sign and type, every key is bounded to the range the model is meant for, so
that no accepted configuration can make the plant, the noise or the reward non-finite (see
:data:`WIND_SPEED_MAX_KMH` and the ``spec`` of each field).

>>> cfg = load_env_config(dt=1e-2, wind_speed_kmh=30)
>>> cfg.dt, cfg.wind_speed_kmh
(0.01, 30.0)
>>> load_env_config(wind_speed_kmh="50")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: keyword arguments: field 'wind_speed_kmh': must be a number ... got '50'
>>> load_env_config(wind_speed_kmh=1e5)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dss14_env.core.schema.ConfigError: keyword arguments: field 'wind_speed_kmh': must be a number ...
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dss14_env.core.schema import ConfigError, Spec, check_value, load_section, read_config, spec
from dss14_env.model.uncertainty import SWEEP_PARAMS

#: scenarios (``scenario`` key)
SCENARIOS = ("hold", "step", "track", "slew")
#: axis selections of ``step_axes`` and ``slew_axes``
AXES_CHOICES = ("az", "el", "both")
#: named wind directions besides an angle in rad (``wind_direction``)
DIRECTION_CHOICES = ("front", "side", "random")
#: named start elevations besides an angle in deg (``start_el_deg``): the model's elevation
#: (:func:`dss14_env.envs.scenarios.start_elevation`) or uniform over ``start_el_range_deg``
START_EL_CHOICES = ("model", "random")
#: what the reward scores (``reward``): the servo error at the drive encoders ([R] Table 4's
#: quantity) or the dish's true pointing error (el and xel, deformation included)
REWARD_CHOICES = ("servo", "pointing")
#: what the encoders measure (``encoders``): the drive angles (the report's computer mode, the
#: default) or the structure's pointing angles at the axes ([R]'s "encoders located close to
#: the axes")
ENCODER_CHOICES = ("drive", "axis")
#: the sensors a controller sees (``sensors``): the encoders (always) and the monopulse feed
#: (:mod:`dss14_env.envs.monopulse`)
SENSOR_CHOICES = ("encoders", "monopulse")
#: the monopulse sensor's bands (``monopulse_band``)
BAND_CHOICES = ("S", "X", "Ka")

#: Largest mean wind speed, km/h (assumed).  The DSN antennas stop tracking and are stowed in
#: high wind, so the model is meant for operating winds: the report's Table 4 is at 50 km/h and
#: the registered variants use 30-70 km/h.  We found no public statement of the 70-m stow limit
#: that we could check; 90 km/h (25 m/s) lies above every speed the report and the presets use
#: and far below the structures' survival specification in stow (44-53 m/s, about 160-190 km/h:
#: JPL DSN Progress Report 42-32, pp. 65-69, 1976).  Beyond it the plant's exact discretisation
#: breaks down numerically (at 1e5 km/h the states overflow to NaN).
WIND_SPEED_MAX_KMH = 90.0
#: shortest and longest control period, s (the observation's error rate divides by dt)
DT_RANGE = (1.0e-3, 0.1)
#: largest rate limit and action scale, deg/s (40 x the 70-m antenna's 0.25 deg/s: keeps every
#: commanded motion, and so the plant state, bounded)
RATE_MAX_DEG_S = 10.0
#: smallest rate limit, action scale (deg/s) and acceleration limit (deg/s^2): below them the
#: action and its cost scale out of floating-point range
RATE_MIN_DEG_S = 1.0e-6
#: largest acceleration limit, deg/s^2
ACCEL_MAX_DEG_S2 = 1.0e3
#: smallest slew rate (deg/s) and acceleration (deg/s^2): below them the profile's timing
#: (distance / rate, rate / acceleration) overflows
SLEW_MIN = 1.0e-6

#: largest wind direction, rad (two turns either way, as the direction grid's +-720 deg)
WIND_DIRECTION_MAX_RAD = 4.0 * math.pi
#: latest time of a step or slew in an episode, s (the longest period of the tracking scenario)
EVENT_TIME_MAX_S = 1.0e7

#: keys that ``reset(options=...)`` may change for one episode
EPISODE_KEYS = frozenset({
    "scenario", "max_error_deg", "start_az_deg", "start_el_deg", "wind_speed_kmh",
    "wind_direction", "step_deg", "step_time_s", "step_axes", "track_rate_max_deg_s",
    "track_amp_max_deg", "track_period_range_s", "slew_deg", "slew_rate_deg_s",
    "slew_accel_deg_s2", "slew_time_s", "slew_axes", "randomize_params", "params"})


def _pair(unit: str, lo: float, hi: float, lo_open: bool = False) -> Any:
    return spec(unit, kind="pair", lo=lo, hi=hi, lo_open=lo_open)


@dataclass(frozen=True)
class EnvConfig:
    """Validated settings of the environments (units in the field names; ``configs/env.yaml``
    documents each key).  Build it with :func:`load_env_config`.
    """

    scenario: str = spec(None, kind="str", choices=SCENARIOS)
    dt: float = spec("s", lo=DT_RANGE[0], hi=DT_RANGE[1])
    action_scale_deg_s: float = spec("deg/s", lo=RATE_MIN_DEG_S, hi=RATE_MAX_DEG_S)
    rate_limit_deg_s: float = spec("deg/s", lo=RATE_MIN_DEG_S, hi=RATE_MAX_DEG_S)
    accel_limit_deg_s2: float = spec("deg/s^2", lo=RATE_MIN_DEG_S, hi=ACCEL_MAX_DEG_S2)
    error_scale_mdeg: float = spec("mdeg", lo=1.0e-3, hi=1.0e6)
    encoders: str = spec(None, kind="str", choices=ENCODER_CHOICES)
    encoder_bits: int | None = spec("1", kind="integer", lo=8, hi=40, optional=True)
    encoder_noise_mdeg: float = spec("mdeg", lo=0.0, hi=1.0e3)
    reward: str = spec(None, kind="str", choices=REWARD_CHOICES)
    action_change_weight: float = spec("1", lo=0.0, hi=1.0e6)
    termination_penalty: float = spec("1", lo=0.0, hi=1.0e9)
    max_error_deg: float = spec("deg", lo=0.0, lo_open=True, hi=180.0)
    el_limits_deg: tuple = _pair("deg", 0.0, 90.0)
    az_wrap_centre_deg: float = spec("deg", lo=-360.0, hi=360.0)
    az_wrap_half_range_deg: float = spec("deg", lo=0.0, lo_open=True, hi=360.0)
    start_az_deg: float | str = spec("deg", lo=-720.0, hi=720.0, choices=("random",))
    start_az_range_deg: tuple = _pair("deg", -720.0, 720.0)
    start_el_deg: float | str = spec("deg", lo=0.0, hi=90.0, choices=START_EL_CHOICES)
    start_el_range_deg: tuple = _pair("deg", 0.0, 90.0)
    wind_speed_kmh: float | str = spec("km/h", lo=0.0, hi=WIND_SPEED_MAX_KMH, choices=("random",))
    wind_speed_grid_kmh: tuple = spec("km/h", kind="list", lo=0.0, hi=WIND_SPEED_MAX_KMH)
    wind_direction: float | str = spec("rad", lo=-WIND_DIRECTION_MAX_RAD, hi=WIND_DIRECTION_MAX_RAD,
                                       choices=DIRECTION_CHOICES)
    wind_direction_grid_deg: tuple = spec("deg", kind="list", lo=-720.0, hi=720.0)
    step_deg: float = spec("deg", lo=-360.0, hi=360.0)
    step_time_s: float = spec("s", lo=0.0, lo_open=True, hi=EVENT_TIME_MAX_S)
    step_axes: str = spec(None, kind="str", choices=AXES_CHOICES)
    track_rate_max_deg_s: float = spec("deg/s", lo=0.0, hi=RATE_MAX_DEG_S)
    track_amp_max_deg: float = spec("deg", lo=0.0, hi=360.0)
    track_period_range_s: tuple = _pair("s", 1.0, 1.0e7)
    slew_deg: float = spec("deg", lo=0.0, hi=720.0)
    slew_rate_deg_s: float = spec("deg/s", lo=SLEW_MIN, hi=RATE_MAX_DEG_S)
    slew_accel_deg_s2: float = spec("deg/s^2", lo=SLEW_MIN, hi=ACCEL_MAX_DEG_S2)
    slew_time_s: float = spec("s", lo=0.0, hi=EVENT_TIME_MAX_S)
    slew_axes: str = spec(None, kind="str", choices=AXES_CHOICES)
    randomize_params: bool = spec(None, kind="bool")
    params: dict | None = spec(None, kind="mapping", optional=True, default=None)
    info_state: bool = spec(None, kind="bool", default=False)
    sensors: tuple = spec(None, kind="list", items=Spec(None, kind="str", choices=SENSOR_CHOICES),
                          default=("encoders",))
    monopulse_band: str = spec(None, kind="str", choices=BAND_CHOICES, default="Ka")
    monopulse_slope: float = spec("1", lo=0.5, hi=4.0, default=1.6)
    monopulse_cnr_dbhz: float | None = spec("dB-Hz", lo=0.0, hi=90.0, optional=True, default=30.0)
    monopulse_bandwidth_hz: float | None = spec("Hz", lo=1.0e-3, hi=1.0e3, optional=True, default=1.0)
    monopulse_update_s: float | None = spec("s", lo=0.0, lo_open=True, hi=10.0, optional=True, default=None)
    monopulse_latency_s: float = spec("s", lo=0.0, hi=10.0, default=0.0)
    render_window_s: float = spec("s", lo=0.0, lo_open=True, hi=600.0, default=20.0)

    def __hash__(self) -> int:  # params is a dict
        return hash(tuple((f.name, repr(getattr(self, f.name))) for f in dataclasses.fields(self)))

    def source_of(self, key: str) -> str:
        """Where a key's value came from (a file, ``keyword arguments``, ``reset options``), for
        messages about it that only the environment can check (e.g. ``params`` against the
        model's ranges).
        """
        return self.__dict__.get("_sources", {}).get(key, "<config>")

    def _with_sources(self, base: Mapping[str, str], keys: Any, source: str) -> EnvConfig:
        object.__setattr__(self, "_sources", {**base, **{str(k): source for k in keys}})
        return self

    def checked(self, source: str) -> EnvConfig:
        """The cross-field rules (each field alone was checked by its spec); ``self`` normalised.

        :param source: where the values came from, for the message
        :raises ConfigError: naming the field
        """

        def bad(name: str, what: str, value: Any) -> ConfigError:
            return ConfigError(f"{source}: field '{name}': must {what}, got {value!r}")

        c, h = self.az_wrap_centre_deg, self.az_wrap_half_range_deg
        lo, hi = c - h, c + h
        travel = f"the azimuth travel az_wrap_centre_deg +- az_wrap_half_range_deg = [{lo:g}, {hi:g}]"
        if not (lo <= self.start_az_range_deg[0] and self.start_az_range_deg[1] <= hi):
            raise bad("start_az_range_deg", f"lie within {travel}", list(self.start_az_range_deg))
        if self.start_az_deg != "random" and not lo <= self.start_az_deg <= hi:
            raise bad("start_az_deg", f"lie within {travel} or be 'random'", self.start_az_deg)
        lo, hi = self.el_limits_deg
        if not (lo <= self.start_el_range_deg[0] and self.start_el_range_deg[1] <= hi):
            raise bad("start_el_range_deg", f"lie within el_limits_deg [{lo:g}, {hi:g}]",
                      list(self.start_el_range_deg))
        if self.start_el_deg not in START_EL_CHOICES and not lo <= self.start_el_deg <= hi:
            raise bad("start_el_deg", f"lie within el_limits_deg [{lo:g}, {hi:g}] or be 'model' or 'random'",
                      self.start_el_deg)
        w = 2.0 * math.pi / self.track_period_range_s[0]
        if self.track_rate_max_deg_s + self.track_amp_max_deg * w > self.rate_limit_deg_s:
            raise bad("track_amp_max_deg", "keep the track's largest rate (track_rate_max_deg_s + "
                      "amplitude x 2 pi / the shortest period of track_period_range_s) within "
                      f"rate_limit_deg_s {self.rate_limit_deg_s:g}", self.track_amp_max_deg)
        if self.track_amp_max_deg * w * w > self.accel_limit_deg_s2:
            raise bad("track_amp_max_deg", "keep the track's largest acceleration (amplitude x (2 pi / "
                      "the shortest period of track_period_range_s)^2) within accel_limit_deg_s2 "
                      f"{self.accel_limit_deg_s2:g}", self.track_amp_max_deg)
        if self.slew_rate_deg_s > self.rate_limit_deg_s:
            raise bad("slew_rate_deg_s", f"be <= rate_limit_deg_s {self.rate_limit_deg_s:g}",
                      self.slew_rate_deg_s)
        if self.sensors[0] != "encoders" or len(set(self.sensors)) != len(self.sensors):
            raise bad("sensors", "list 'encoders' first, each sensor once (e.g. [encoders, monopulse])",
                      list(self.sensors))
        n_u = whole_steps(self.monopulse_update_s, self.dt, 1)
        if n_u is None:
            raise bad("monopulse_update_s", f"be null or a whole multiple of dt = {self.dt:g} s",
                      self.monopulse_update_s)
        if whole_steps(self.monopulse_latency_s, self.dt, 0) is None:
            raise bad("monopulse_latency_s", f"be a whole multiple (>= 0) of dt = {self.dt:g} s",
                      self.monopulse_latency_s)
        b = self.monopulse_bandwidth_hz
        if b is not None and b > 0.5 / (n_u * self.dt):
            raise bad("monopulse_bandwidth_hz", f"be <= the update rate's Nyquist frequency 1 / (2 x "
                      f"{n_u * self.dt:g} s) (the update period monopulse_update_s, default dt)", b)
        if self.slew_accel_deg_s2 > self.accel_limit_deg_s2:
            raise bad("slew_accel_deg_s2", f"be <= accel_limit_deg_s2 {self.accel_limit_deg_s2:g}",
                      self.slew_accel_deg_s2)
        return dataclasses.replace(self, params=_check_params(self.params, source))

    def updated(self, changes: Mapping[str, Any], source: str) -> EnvConfig:
        """A checked copy with some keys changed.

        :param changes: ``{key: value}``
        :param source: where the changes come from (a file, ``keyword arguments``, ...)
        :raises ConfigError: an unknown key or a bad value, naming it and the source
        """
        if not isinstance(changes, Mapping):
            raise ConfigError(f"{source}: must be a mapping of fields, got {type(changes).__name__}")
        if not changes:
            return self
        merged = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        merged.update(changes)
        new = load_section(EnvConfig, merged, source).checked(source)
        return new._with_sources(self.__dict__.get("_sources", {}), changes, source)

    def replace(self, **changes: Any) -> EnvConfig:
        """Checked copy with some keys changed (``ConfigError`` on an unknown key or bad value)."""
        return self.updated(changes, "keyword arguments")

    def with_options(self, options: Mapping[str, Any] | None) -> EnvConfig:
        """The configuration of one episode: ``self`` with ``reset(options=...)`` applied.

        :raises ConfigError: on an option that is not an episode key (:data:`EPISODE_KEYS`) or
            has a bad value, naming it
        """
        if options is None:
            return self
        if not isinstance(options, Mapping):
            raise ConfigError(f"reset options: must be a mapping of episode keys or None, got "
                              f"{type(options).__name__}")
        bad = sorted((k for k in options if not isinstance(k, str) or k not in EPISODE_KEYS), key=repr)
        if bad:
            raise ConfigError(f"reset options: field {bad[0]!r}: must be an episode key (one of "
                              f"{', '.join(sorted(EPISODE_KEYS))}), got {_short(options[bad[0]])}")
        return self.updated(options, "reset options")

    def as_dict(self) -> dict[str, Any]:
        """The keys and values (lists for pairs and grids), as in ``configs/env.yaml``."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in dataclasses.fields(self)}


def whole_steps(seconds: float | None, dt: float, least: int) -> int | None:
    """A duration as a whole number (>= ``least``) of control periods ``dt``: None for a
    duration that is not one (within 1e-9 relative); ``least`` for None.

    >>> whole_steps(0.1, 0.02, 1), whole_steps(0.03, 0.02, 1), whole_steps(None, 0.02, 1)
    (5, None, 1)
    """
    if seconds is None:
        return least
    n = round(seconds / dt)
    if n < least or abs(n * dt - seconds) > 1e-9 * max(seconds, dt):
        return None
    return int(n)


def _short(value: Any) -> str:
    """``repr(value)`` on one line of at most 80 characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 80 else text[:77] + "..."


def _check_params(params: Mapping[str, Any] | None, source: str) -> dict[str, float] | None:
    """``params``: names of :data:`dss14_env.model.uncertainty.SWEEP_PARAMS`, positive finite SI
    values (the model's ranges are checked where the model is known, by the plant factory).
    """
    if params is None:
        return None
    out = {}
    item = Spec("1", lo=0.0, lo_open=True)
    for name, value in params.items():
        if name not in SWEEP_PARAMS:
            raise ConfigError(f"{source}: field 'params': must name parameters of "
                              f"{', '.join(SWEEP_PARAMS)}, got {name!r}")
        out[name] = check_value(item, value, f"{source}: field 'params.{name}'")
    return out


def load_env_config(config: str | Path | Mapping[str, Any] | EnvConfig | None = None,
                    **overrides: Any) -> EnvConfig:
    """Read and check the environment configuration.

    :param config: a YAML file or the name of a shipped one, a mapping of keys, an
        :class:`EnvConfig`, or None for the shipped ``configs/env.yaml``; a file or mapping may
        give only some keys (the others come from ``configs/env.yaml``)
    :param overrides: keys replacing those of ``config``
    :return: the checked configuration
    :raises ConfigError: naming the source and the first unknown key or bad value
    """
    if isinstance(config, EnvConfig):
        base = config
    else:
        data, source = read_config("env")
        base = load_section(EnvConfig, data, source, defaults=False).checked(source)
        base = base._with_sources({}, data, source)
        if isinstance(config, (str, Path)):
            data, source = read_config(config, kind="environment")
            base = base.updated(data, source)
        elif config is not None:
            base = base.updated(config, "config mapping")
    return base.updated(overrides, "keyword arguments")
