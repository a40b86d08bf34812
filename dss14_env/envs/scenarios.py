"""Configuration, scenarios and the per-episode draw of the DSS14 environments.

:class:`EnvConfig` holds the settings of ``configs/env.yaml`` (units in the key names: deg,
mdeg, s, km/h); :func:`load_env_config` reads and validates them, and
:meth:`EnvConfig.with_options` applies ``reset(options=...)``.  Every bad value raises a
``ValueError`` that names the key.

:func:`draw_episode` draws one episode from a ``numpy.random.Generator`` -- the single
environment and every sub-environment of the vector environment call it with their own
generator, in the same order, so both give the same episodes for the same seeds:

1. hydraulic parameters (only with ``randomize_params``; rejection sampling, stable part);
2. mean wind speed (only if ``"random"``: an index into ``wind_speed_grid_kmh``);
3. wind direction (only if ``"random"``: an index into ``wind_direction_grid_deg``);
4. start azimuth, then start elevation (only if ``"random"``: uniform over their ranges);
5. scenario parameters: ``track`` draws rate, amplitude, period and phase (2 each, in that
   order), ``slew`` draws the two signs, ``hold`` and ``step`` draw nothing;
6. the standard normals (one per filter state, 4) of the stationary gust-filter state.

After that the environment draws the episode's first noise block (:func:`draw_noise_block`).

Command trajectories (per axis, relative to the start position, all zero at t = 0)::

    c(t) = v t + A (sin(w t + phi) - sin(phi))      track: sidereal-like rate + slow sinusoid
         + S H(t - t_s)                             step (H: unit step, t_s > 0)
         + s(t - t_0)                               slew: trapezoidal-rate profile, s(T) = D

:func:`command` evaluates ``c`` and ``dc/dt`` for any batch of times and parameter sets.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np
import yaml

if TYPE_CHECKING:
    from dss14_env.envs.plant import Plant

SCENARIOS = ("hold", "step", "track", "slew")
AXES_CHOICES = ("az", "el", "both")
#: steps per noise block: each episode draws its noise ``NOISE_BLOCK`` steps at a time
NOISE_BLOCK = 256
DEG = math.pi / 180.0
MDEG = math.pi / 180.0e3
KMH = 1.0 / 3.6

#: keys that ``reset(options=...)`` may change for one episode
EPISODE_KEYS = frozenset({
    "scenario", "max_error_deg", "start_az_deg", "start_el_deg", "wind_speed_kmh",
    "wind_direction", "step_deg", "step_time_s", "step_axes", "track_rate_max_deg_s",
    "track_amp_max_deg", "track_period_range_s", "slew_deg", "slew_rate_deg_s",
    "slew_accel_deg_s2", "slew_time_s", "slew_axes", "randomize_params", "params"})


def default_env_config_path() -> Path:
    """Path of the shipped ``configs/env.yaml``."""
    from dss14_env.core.schema import default_config_path

    return default_config_path("env.yaml")


# ---------------------------------------------------------------------------- validation
def _num(key: str, v: Any, *, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, what: str = "") -> float:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"config key {key!r} must be a number{what}, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"config key {key!r} must be finite{what}, got {v!r}")
    if lo is not None and (x <= lo if lo_open else x < lo):
        raise ValueError(f"config key {key!r} must be {'>' if lo_open else '>='} {lo:g}{what}, got {v!r}")
    if hi is not None and x > hi:
        raise ValueError(f"config key {key!r} must be <= {hi:g}{what}, got {v!r}")
    return x


def _pair(key: str, v: Any, *, lo: float | None = None, hi: float | None = None,
          lo_open: bool = False) -> tuple[float, float]:
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) != 2:
        raise ValueError(f"config key {key!r} must be a pair [low, high], got {v!r}")
    a = _num(key, v[0], lo=lo, hi=hi, lo_open=lo_open)
    b = _num(key, v[1], lo=lo, hi=hi, lo_open=lo_open)
    if a > b:
        raise ValueError(f"config key {key!r} must have low <= high, got {v!r}")
    return a, b


def _grid(key: str, v: Any, *, lo: float | None = None) -> tuple[float, ...]:
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) == 0:
        raise ValueError(f"config key {key!r} must be a non-empty list of numbers, got {v!r}")
    return tuple(_num(key, x, lo=lo) for x in v)


def _choice(key: str, v: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(v, str) or v not in choices:
        raise ValueError(f"config key {key!r} must be one of {list(choices)}, got {v!r}")
    return v


def _flag(key: str, v: Any) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise ValueError(f"config key {key!r} must be true or false, got {v!r}")
    return bool(v)


def _random_or_num(key: str, v: Any, **kw) -> float | str:
    if isinstance(v, str):
        if v != "random":
            raise ValueError(f"config key {key!r} must be a number or 'random', got {v!r}")
        return v
    return _num(key, v, **kw)


def _direction(key: str, v: Any) -> float | str:
    if isinstance(v, str):
        if v not in ("front", "side", "random"):
            raise ValueError(f"config key {key!r} must be 'front', 'side', 'random' or an angle in "
                             f"rad, got {v!r}")
        return v
    return _num(key, v, what=" (rad)")


def _params(key: str, v: Any) -> dict[str, float] | None:
    if v is None:
        return None
    if not isinstance(v, Mapping):
        raise ValueError(f"config key {key!r} must be null or a mapping {{name: SI value}}, got {v!r}")
    from dss14_env.model.uncertainty import SWEEP_PARAMS  # lazy: keeps `import dss14_env` light

    out = {}
    for name, val in v.items():
        if name not in SWEEP_PARAMS:
            raise ValueError(f"config key {key!r}: unknown parameter {name!r}; known: {list(SWEEP_PARAMS)}")
        out[name] = _num(f"{key}.{name}", val, lo=0.0, lo_open=True)
    return out


@dataclass(frozen=True)
class EnvConfig:
    """Validated settings of the environment (units in the field names; see ``configs/env.yaml``).

    Build it with :func:`load_env_config`; fields are checked in :meth:`validated`.
    """

    scenario: str
    dt: float
    action_scale_deg_s: float
    rate_limit_deg_s: float
    accel_limit_deg_s2: float
    error_scale_mdeg: float
    encoder_bits: int | None
    encoder_noise_mdeg: float
    action_change_weight: float
    termination_penalty: float
    max_error_deg: float
    el_limits_deg: tuple[float, float]
    az_wrap_centre_deg: float
    az_wrap_half_range_deg: float
    start_az_deg: float | str
    start_az_range_deg: tuple[float, float]
    start_el_deg: float | str
    start_el_range_deg: tuple[float, float]
    wind_speed_kmh: float | str
    wind_speed_grid_kmh: tuple[float, ...]
    wind_direction: float | str
    wind_direction_grid_deg: tuple[float, ...]
    step_deg: float
    step_time_s: float
    step_axes: str
    track_rate_max_deg_s: float
    track_amp_max_deg: float
    track_period_range_s: tuple[float, float]
    slew_deg: float
    slew_rate_deg_s: float
    slew_accel_deg_s2: float
    slew_time_s: float
    slew_axes: str
    randomize_params: bool
    params: dict | None = field(default=None, hash=False, compare=True)
    info_state: bool = False
    render_window_s: float = 20.0

    def validated(self) -> "EnvConfig":
        """Return a copy with every field checked and normalised (``ValueError`` naming the key)."""
        f: dict[str, Any] = {}
        f["scenario"] = _choice("scenario", self.scenario, SCENARIOS)
        f["dt"] = _num("dt", self.dt, lo=0.0, lo_open=True, hi=0.1, what=" (s)")
        f["action_scale_deg_s"] = _num("action_scale_deg_s", self.action_scale_deg_s, lo=0.0, lo_open=True)
        f["rate_limit_deg_s"] = _num("rate_limit_deg_s", self.rate_limit_deg_s, lo=0.0, lo_open=True)
        f["accel_limit_deg_s2"] = _num("accel_limit_deg_s2", self.accel_limit_deg_s2, lo=0.0, lo_open=True)
        f["error_scale_mdeg"] = _num("error_scale_mdeg", self.error_scale_mdeg, lo=0.0, lo_open=True)
        bits = self.encoder_bits
        if bits is not None:
            if isinstance(bits, (bool, np.bool_)) or not isinstance(bits, (int, np.integer)) or not 8 <= bits <= 40:
                raise ValueError(f"config key 'encoder_bits' must be null or an integer 8..40, got {bits!r}")
            bits = int(bits)
        f["encoder_bits"] = bits
        f["encoder_noise_mdeg"] = _num("encoder_noise_mdeg", self.encoder_noise_mdeg, lo=0.0)
        f["action_change_weight"] = _num("action_change_weight", self.action_change_weight, lo=0.0)
        f["termination_penalty"] = _num("termination_penalty", self.termination_penalty, lo=0.0)
        f["max_error_deg"] = _num("max_error_deg", self.max_error_deg, lo=0.0, lo_open=True)
        f["el_limits_deg"] = _pair("el_limits_deg", self.el_limits_deg, lo=0.0, hi=90.0)
        f["az_wrap_centre_deg"] = _num("az_wrap_centre_deg", self.az_wrap_centre_deg)
        f["az_wrap_half_range_deg"] = _num("az_wrap_half_range_deg", self.az_wrap_half_range_deg,
                                           lo=0.0, lo_open=True)
        c, h = f["az_wrap_centre_deg"], f["az_wrap_half_range_deg"]
        f["start_az_range_deg"] = _pair("start_az_range_deg", self.start_az_range_deg, lo=c - h, hi=c + h)
        f["start_az_deg"] = _random_or_num("start_az_deg", self.start_az_deg, lo=c - h, hi=c + h)
        lo, hi = f["el_limits_deg"]
        f["start_el_range_deg"] = _pair("start_el_range_deg", self.start_el_range_deg, lo=lo, hi=hi)
        f["start_el_deg"] = _random_or_num("start_el_deg", self.start_el_deg, lo=lo, hi=hi)
        f["wind_speed_kmh"] = _random_or_num("wind_speed_kmh", self.wind_speed_kmh, lo=0.0, what=" (km/h)")
        f["wind_speed_grid_kmh"] = _grid("wind_speed_grid_kmh", self.wind_speed_grid_kmh, lo=0.0)
        f["wind_direction"] = _direction("wind_direction", self.wind_direction)
        f["wind_direction_grid_deg"] = _grid("wind_direction_grid_deg", self.wind_direction_grid_deg)
        f["step_deg"] = _num("step_deg", self.step_deg)
        f["step_time_s"] = _num("step_time_s", self.step_time_s, lo=0.0, lo_open=True)
        f["step_axes"] = _choice("step_axes", self.step_axes, AXES_CHOICES)
        f["track_rate_max_deg_s"] = _num("track_rate_max_deg_s", self.track_rate_max_deg_s, lo=0.0)
        f["track_amp_max_deg"] = _num("track_amp_max_deg", self.track_amp_max_deg, lo=0.0)
        f["track_period_range_s"] = _pair("track_period_range_s", self.track_period_range_s, lo=0.0,
                                          lo_open=True)
        w = 2.0 * math.pi / f["track_period_range_s"][0]
        if f["track_rate_max_deg_s"] + f["track_amp_max_deg"] * w > f["rate_limit_deg_s"]:
            raise ValueError("config keys 'track_rate_max_deg_s', 'track_amp_max_deg', "
                             "'track_period_range_s': the track's largest rate exceeds rate_limit_deg_s")
        if f["track_amp_max_deg"] * w * w > f["accel_limit_deg_s2"]:
            raise ValueError("config keys 'track_amp_max_deg', 'track_period_range_s': the track's "
                             "largest acceleration exceeds accel_limit_deg_s2")
        f["slew_deg"] = _num("slew_deg", self.slew_deg, lo=0.0)
        f["slew_rate_deg_s"] = _num("slew_rate_deg_s", self.slew_rate_deg_s, lo=0.0, lo_open=True,
                                    hi=f["rate_limit_deg_s"])
        f["slew_accel_deg_s2"] = _num("slew_accel_deg_s2", self.slew_accel_deg_s2, lo=0.0, lo_open=True,
                                      hi=f["accel_limit_deg_s2"])
        f["slew_time_s"] = _num("slew_time_s", self.slew_time_s, lo=0.0)
        f["slew_axes"] = _choice("slew_axes", self.slew_axes, AXES_CHOICES)
        f["randomize_params"] = _flag("randomize_params", self.randomize_params)
        f["params"] = _params("params", self.params)
        f["info_state"] = _flag("info_state", self.info_state)
        f["render_window_s"] = _num("render_window_s", self.render_window_s, lo=0.0, lo_open=True)
        return dataclasses.replace(self, **f)

    def replace(self, **changes: Any) -> "EnvConfig":
        """Validated copy with some keys changed (``ValueError`` on an unknown key or bad value)."""
        unknown = sorted(set(changes) - _FIELDS)
        if unknown:
            raise ValueError(f"unknown config key(s) {unknown}; known: {sorted(_FIELDS)}")
        return dataclasses.replace(self, **changes).validated()

    def with_options(self, options: Mapping[str, Any] | None) -> "EnvConfig":
        """The configuration of one episode: ``self`` with ``reset(options=...)`` applied.

        :raises ValueError: on an option that is not an episode key (:data:`EPISODE_KEYS`) or
            has a bad value, naming it
        """
        if not options:
            return self
        if not isinstance(options, Mapping):
            raise ValueError(f"reset options must be a mapping, got {type(options).__name__}")
        bad = sorted(set(options) - EPISODE_KEYS)
        if bad:
            raise ValueError(f"unknown reset option(s) {bad}; allowed: {sorted(EPISODE_KEYS)}")
        return self.replace(**dict(options))


_FIELDS = frozenset(f.name for f in dataclasses.fields(EnvConfig))


def load_env_config(config: str | Path | Mapping[str, Any] | EnvConfig | None = None,
                    **overrides: Any) -> EnvConfig:
    """Read and validate the environment configuration.

    :param config: a YAML file, a mapping of keys, an :class:`EnvConfig`, or None for the
        shipped ``configs/env.yaml``; a mapping or file may give only some keys (the others
        come from ``configs/env.yaml``)
    :param overrides: keys replacing those of ``config``
    :return: the validated configuration
    :raises ValueError: naming the first unknown key or bad value
    """
    if isinstance(config, EnvConfig):
        base = config
    else:
        data = dict(_read(default_env_config_path()))
        if config is not None:
            extra = _read(Path(config)) if isinstance(config, (str, Path)) else config
            if not isinstance(extra, Mapping):
                raise ValueError(f"config must be a mapping, a YAML file or None, got {type(extra).__name__}")
            data.update(extra)
        unknown = sorted(set(data) - _FIELDS)
        if unknown:
            raise ValueError(f"unknown config key(s) {unknown}; known: {sorted(_FIELDS)}")
        missing = sorted(f.name for f in dataclasses.fields(EnvConfig)
                         if f.name not in data and f.default is dataclasses.MISSING)
        if missing:
            raise ValueError(f"config key(s) {missing} missing")
        base = EnvConfig(**data)
    return base.replace(**overrides) if overrides else base.validated()


def _read(path: Path) -> Mapping[str, Any]:
    if not path.is_file():
        raise ValueError(f"config file not found: {path}")
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, Mapping):
        raise ValueError(f"config file {path} must hold a mapping of keys")
    return data


# ---------------------------------------------------------------------------- trajectories
def _axes_mask(axes: str) -> np.ndarray:
    return np.array([axes in ("az", "both"), axes in ("el", "both")], float)


def trajectory(cfg: EnvConfig, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Command-trajectory parameters of one episode (SI, arrays of shape ``(2,)``: az, el).

    Draws from ``rng`` for ``track`` (rates, amplitudes, periods, phases) and ``slew`` (signs).
    """
    z = np.zeros(2)
    tr = {"v": z.copy(), "amp": z.copy(), "omega": z.copy(), "phase": z.copy(),
          "step": z.copy(), "t_step": np.full(2, math.inf),
          "slew_acc": z.copy(), "slew_t0": z.copy(), "slew_ta": z.copy(), "slew_T": z.copy()}
    s = cfg.scenario
    if s == "track":
        tr["v"] = rng.uniform(-1.0, 1.0, 2) * cfg.track_rate_max_deg_s * DEG
        tr["amp"] = rng.uniform(0.0, 1.0, 2) * cfg.track_amp_max_deg * DEG
        lo, hi = cfg.track_period_range_s
        tr["omega"] = 2.0 * math.pi / rng.uniform(lo, hi, 2)
        tr["phase"] = rng.uniform(0.0, 2.0 * math.pi, 2)
    elif s == "step":
        tr["step"] = _axes_mask(cfg.step_axes) * cfg.step_deg * DEG
        tr["t_step"] = np.full(2, cfg.step_time_s)
    elif s == "slew":
        sign = 2.0 * rng.integers(0, 2, 2) - 1.0
        dist = cfg.slew_deg * DEG
        rate, acc = cfg.slew_rate_deg_s * DEG, cfg.slew_accel_deg_s2 * DEG
        ta = rate / acc
        if dist < rate * ta:  # triangular profile: the cruise rate is never reached
            ta = math.sqrt(dist / acc)
            rate = acc * ta
        T = dist / rate + ta if dist > 0 else 0.0
        tr["slew_acc"] = sign * acc * _axes_mask(cfg.slew_axes) * (dist > 0)
        tr["slew_t0"] = np.full(2, cfg.slew_time_s)
        tr["slew_ta"] = np.full(2, ta)
        tr["slew_T"] = np.full(2, T)
    tr["sin_phase"] = np.sin(tr["phase"])
    return tr


def command_parts(tr: Mapping[str, np.ndarray]) -> tuple[bool, bool, bool]:
    """Which terms of :func:`command` are non-zero: ``(track, step, slew)``."""
    return (bool(tr["v"].any() or tr["amp"].any()), bool(tr["step"].any()), bool(tr["slew_acc"].any()))


def command(tr: Mapping[str, np.ndarray], t: np.ndarray,
            parts: tuple[bool, bool, bool] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Commanded positions and rates relative to the start (rad, rad/s).

    :param tr: trajectory parameters, arrays of shape ``(..., 2)`` (:func:`trajectory`, or a
        stack of them)
    :param t: times, s, shape broadcastable to ``tr``'s leading shape (e.g. ``(B,)`` for one
        parameter set, ``(N,)`` for N stacked sets)
    :param parts: :func:`command_parts` of ``tr`` if known (skipping zero terms changes nothing)
    :return: ``(c, c_dot)``, each of shape ``(..., 2)``

    >>> import numpy as np
    >>> cfg = load_env_config(scenario="slew", slew_deg=1.0)
    >>> tr = trajectory(cfg, np.random.default_rng(0))
    >>> c, cd = command(tr, np.array([0.0, 100.0]))
    >>> np.round(np.abs(np.degrees(c[1])), 9).tolist(), np.abs(cd[1]).tolist()
    ([1.0, 1.0], [0.0, 0.0])
    """
    track, step, slew = command_parts(tr) if parts is None else parts
    t = np.asarray(t, float)[..., None]
    if track:
        wt = tr["omega"] * t + tr["phase"]
        c = tr["v"] * t + tr["amp"] * (np.sin(wt) - tr["sin_phase"])
        cd = tr["v"] + tr["amp"] * tr["omega"] * np.cos(wt)
    else:
        c = np.zeros(np.broadcast_shapes(t.shape, tr["v"].shape))
        cd = np.zeros_like(c)
    if step:
        c = c + tr["step"] * (t >= tr["t_step"])
    if slew:
        acc = tr["slew_acc"]
        tau = t - tr["slew_t0"]
        ta, T = tr["slew_ta"], tr["slew_T"]
        r1, r2 = np.maximum(tau, 0.0), np.maximum(tau - ta, 0.0)
        r3, r4 = np.maximum(tau - (T - ta), 0.0), np.maximum(tau - T, 0.0)
        c = c + 0.5 * acc * (r1 * r1 - r2 * r2 - r3 * r3 + r4 * r4)
        cd = cd + acc * (r1 - r2 - r3 + r4)
    return c, cd


# ---------------------------------------------------------------------------- episodes
@dataclass
class Episode:
    """Everything drawn at a reset (SI).

    :param cfg: the episode's configuration (options applied)
    :param plant: the discretised plant (:class:`dss14_env.envs.plant.Plant`)
    :param wind_speed: mean wind speed, m/s
    :param wind_direction: wind direction relative to the dish, rad (0 front, pi/2 side)
    :param kappa: direction factors of the plant's two gust-filter copies
    :param t_mean: mean wind torques ``[Tw_az, Tw_el]``, N*m
    :param start: absolute start position ``[az, el]``, rad
    :param traj: command-trajectory parameters (:func:`trajectory`)
    :param x0: initial joint plant state (balanced)
    :param r0: rate command holding the initial steady motion, rad/s
    :param params: hydraulic parameters of the plant (empty = nominal)
    """

    cfg: EnvConfig
    plant: Plant
    wind_speed: float
    wind_direction: float
    kappa: np.ndarray
    t_mean: np.ndarray
    start: np.ndarray
    traj: dict
    x0: np.ndarray
    r0: np.ndarray
    params: dict


def draw_episode(cfg: EnvConfig, rng: np.random.Generator) -> Episode:
    """Draw one episode (see the module docstring for the order of the draws).

    The plant starts in steady motion: the rate loop is in the steady state that moves both
    encoders at the command's initial rate from the start position under the wind torque at
    t = 0 (mean plus the initial gust, held), the gust filter in its stationary distribution,
    and the previous rate command is the one that holds this motion (``r0``).  With a PI
    controller that starts bumplessly from ``r0`` there is no start transient to discard.
    """
    from dss14_env.envs.plant import get_plant
    from dss14_env.model.uncertainty import draw_stable_params

    if cfg.params is not None:
        params = dict(cfg.params)
    elif cfg.randomize_params:
        params = draw_stable_params(rng)
    else:
        params = {}
    if cfg.wind_speed_kmh == "random":
        grid = cfg.wind_speed_grid_kmh
        speed = grid[int(rng.integers(len(grid)))] * KMH
    else:
        speed = float(cfg.wind_speed_kmh) * KMH
    wd = cfg.wind_direction
    if wd == "random":
        grid = cfg.wind_direction_grid_deg
        direction = grid[int(rng.integers(len(grid)))] * DEG
    else:
        direction = {"front": 0.0, "side": 0.5 * math.pi}.get(wd, wd)  # type: ignore[arg-type]
    start = np.empty(2)
    for i, (val, rng_range) in enumerate(((cfg.start_az_deg, cfg.start_az_range_deg),
                                          (cfg.start_el_deg, cfg.start_el_range_deg))):
        start[i] = (rng.uniform(*rng_range) if val == "random" else float(val)) * DEG
    tr = trajectory(cfg, rng)
    plant = get_plant(speed, cfg.dt, params)  # no draws
    xi = rng.standard_normal(plant.n_wind)
    kappa = plant.kappa(direction)
    t_mean = plant.mean_torque(direction)
    x_wind = plant.filter_state(kappa, xi)
    _, cd0 = command(tr, np.zeros(1))
    x0, r0 = plant.steady_start(x_wind, t_mean, cd0[0])
    return Episode(cfg, plant, speed, float(direction), kappa, t_mean, start, tr, x0, r0, params)


def block_rows(tr: Mapping[str, np.ndarray], k0: int, dt: float, rate_limit: float,
               normals: np.ndarray, encoder_sigma: float, out: np.ndarray | None = None) -> np.ndarray:
    """Per-step rows of the steps ``k0 .. k0 + NOISE_BLOCK - 1`` of one or more episodes.

    Row ``j`` is ``[c (2), c in deg (2), c_dot / rate_limit (2), xi (k), encoder noise (2)]``:
    the command at the end of step ``k0 + j`` (``t = (k0 + j + 1) dt``) and the step's noise
    (zeros for the encoder noise when there is none).  The single and the vector environment
    both build their rows here, so they agree exactly.

    :param tr: trajectory parameters, arrays ``(2,)`` for one episode, or ``(1, N, 2)`` for N
        stacked episodes (then the block is time-major: ``(NOISE_BLOCK, N, ...)``)
    :param k0: first step of the block
    :param dt: control period, s
    :param rate_limit: rate limit, rad/s (scales c_dot)
    :param normals: :func:`draw_noise_block` output ``(NOISE_BLOCK, k [+ 2])``, or
        ``(NOISE_BLOCK, N, k [+ 2])`` for stacked episodes
    :param encoder_sigma: encoder noise std, rad (0: the normals have no encoder columns)
    :param out: array to write the rows to (default: a new one)
    :return: ``(NOISE_BLOCK, [N,] 6 + k + 2)``
    """
    t = (np.arange(k0 + 1, k0 + 1 + NOISE_BLOCK) * dt).reshape((NOISE_BLOCK,) + (1,) * (normals.ndim - 2))
    c, cd = command(tr, t)
    k = normals.shape[-1] - (2 if encoder_sigma else 0)
    if out is None:
        out = np.empty(normals.shape[:-1] + (8 + k,))
    out[..., 0:2] = c
    np.multiply(c, 180.0 / math.pi, out=out[..., 2:4])
    np.multiply(cd, 1.0 / rate_limit, out=out[..., 4:6])
    out[..., 6:6 + k] = normals[..., :k]
    if encoder_sigma:
        np.multiply(normals[..., k:], encoder_sigma, out=out[..., 6 + k:])
    else:
        out[..., 6 + k:] = 0.0
    return out


def draw_noise_block(rng: np.random.Generator, noise_rank: int, encoder_noise: bool) -> np.ndarray:
    """Standard normals for the next :data:`NOISE_BLOCK` steps of one episode.

    :return: ``(NOISE_BLOCK, noise_rank + 2)`` with encoder noise (az, el in the last two
        columns), else ``(NOISE_BLOCK, noise_rank)``
    """
    return rng.standard_normal((NOISE_BLOCK, noise_rank + (2 if encoder_noise else 0)))
