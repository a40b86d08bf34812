"""What sits between a policy and the DSS14 environment: observation features and action map.

One :class:`PolicyInterface` (numpy over N rows = sub-environments) turns the environment's
12 observations into the policy's observation and the policy's output ``u in [-1, 1]^2``
into the environment's action, the same way for training (the Gymnasium wrapper
:class:`InterfaceWrapper` with N = 1; the SB3 ``VecEnvWrapper``
:class:`dss14_env.agents.vec_env.InterfaceVecEnv` over
a batched vector env) and for scoring (:class:`dss14_env.agents.policy.PolicyController`).
:class:`InterfaceSpec` says what it does:

* ``base``: a controller run alongside -- ``"pi"``: the report's PI ([R] Eqs. 57-58,
  :class:`dss14_env.baselines.pi.PIController`); ``"lqg"``: the project's LQG
  (:class:`dss14_env.baselines.lqg.LQGController`, one per row: steady-state Kalman filter +
  LQR); ``"lqg_pointing"``: the LQG designed for the dish's true pointing error
  (:class:`dss14_env.baselines.lqg.PointingLQGController`: the same Kalman filter on the drive
  encoders, the LQR scoring the structure's pointing; its features are the LQG's);
  ``"lqg_pointing_sched"``: that LQG scheduled on the episode's mean wind speed reading
  (:class:`dss14_env.baselines.scheduled.ScheduledPointingLQGController`; command and
  disturbance features only): each row's episode is designed for its own environment's
  reading (:meth:`PolicyInterface.set_wind_readings`, or a ``wind_source`` the rows' readings
  are taken from at every (auto)reset), a row without one for the speed inferred from its
  start command; None: no base controller.
* ``action``: ``"absolute"`` -- the policy's output is the rate command (action units);
  ``"residual"`` -- ``a = a_base + residual_scale * u`` (residual policy learning: Johannink et
  al., *Residual Reinforcement Learning for Robot Control*, ICRA 2019; Silver et al.,
  *Residual Policy Learning*, arXiv:1812.06298, 2018); at ``u = 0`` the loop is the base
  controller's exactly; ``"feedforward"`` -- ``a = feedforward_gain * c_dot + residual_scale *
  g(u)``: the commanded trajectory's rate ``c_dot`` (the observation's ``command_rate``, in
  action units) fed forward, no controller underneath: the policy closes the loop alone.
  ``g(u) = sinh(action_curve u) / sinh(action_curve)`` (``action_curve`` 0: ``g(u) = u``) gives
  fine commands near ``u = 0`` and the full scale at ``|u| = 1``: its slope at 0 is
  ``action_curve / sinh(action_curve)`` (0.147 at 4).
* observation: the environment's entries ``obs_entries`` (default all 12; e.g.
  :data:`NO_ABSOLUTE_ANGLES` leaves out the absolute command and encoder angles 4, 5, 8, 9,
  which in a hold are constants that only tell the random start position; with ``obs_symlog``
  the entries and their history as ``sign(x) log(1 + |x|)`` of their values in mdeg and mdeg/s
  -- :func:`symlog_observation`: a 1-mdeg hold error and a 100-mdeg step both well inside the
  network's range, as the symlog inputs of Hafner et al., *Mastering Diverse Domains through
  World Models*, arXiv:2301.04104, 2023), then the base
  controller's features -- PI: its integral term ``ki I`` in action units (2; controller state
  a memoryless network cannot rebuild); LQG (``estimate=True``; which ones: ``lqg_features``,
  default all, 12): ``"command"`` its command (2), ``"disturbance"`` its input-disturbance
  estimate (2), and its Kalman state estimate about the reference, ``dx = x^ - x_ref``, seen
  through the encoder outputs (``"output"``: ``C dx``, 2, error-scale units) and through the
  three terms of the LQR law ``r = r_ss - Kx dx - Ki xi - Ku (r_prev - r_ss)`` (``"law"``: 2
  each, 6; action units) -- features whose meaning does not depend on the design the LQG picks
  per episode -- then, with ``history`` H > 0, the H previous values of the
  ``history_entries`` of the observation, newest first (frame stacking; at an episode's first
  step the first observation repeated, the steady state the episode starts in), then the
  low-passed entries (``history_filters``), then the ``context``: constants of the environment's
  configuration that a user knows before the first step (:data:`CONTEXTS`; ``"axis_encoders"``:
  1 where the encoders sit at the axes, 0 at the drives; ``"wind_reading"``: the episode's mean
  wind speed reading over 90 km/h, 0 without one), so that one policy may learn a law per
  configuration (gain scheduling on a known quantity, as the report designs its loop per encoder
  location).

Rows restart independently (:meth:`PolicyInterface.restart`), so a vector environment's
auto-reset sub-environments start fresh while the others go on.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dss14_env.agents.base_rows import RowGroupedLQG, batched_base, batched_lqg
from dss14_env.baselines.design import default_controllers_config
from dss14_env.baselines.lqg import LQGController
from dss14_env.baselines.pi import PIController
from dss14_env.baselines.scheduled import MAX_READING, check_readings
from dss14_env.core.units import DEG, MDEG
from dss14_env.envs.core import OBS, OBS_HIGH, OBS_SIZE, as_actions

#: bound of the extra observation entries (integral term, estimates), for the Box only
FEATURE_BOUND = 1.0e3
#: observation entries kept in the history by default: servo errors, previous applied rates
#: (entries 0, 1, 10, 11)
HISTORY_ENTRIES = OBS.entries("error", "prev_rate")
#: the observation without the absolute command and encoder angles (entries 4, 5, 8, 9)
NO_ABSOLUTE_ANGLES = OBS.entries("error", "error_rate", "command_rate", "prev_rate")
#: the LQG features and their widths, in the order they appear (module doc)
LQG_FEATURE_WIDTHS = {"command": 2, "disturbance": 2, "output": 2, "law": 6}
#: the action maps (:class:`InterfaceSpec`)
ACTIONS = ("absolute", "residual", "feedforward")
#: the base controllers: None, the PI, and the LQG designs (encoder or pointing error)
BASES = (None, "pi", "lqg", "lqg_pointing", "lqg_pointing_sched")
LQG_BASES = ("lqg", "lqg_pointing", "lqg_pointing_sched")
#: the base scheduled on each row's mean wind speed reading
SCHEDULED_BASE = "lqg_pointing_sched"
#: the context features (:class:`InterfaceSpec` ``context``): name -> its value for an
#: environment configuration
CONTEXTS = {"axis_encoders": lambda cfg: 1.0 if getattr(cfg, "encoders", None) == "axis" else 0.0,
            "wind_reading": lambda cfg: 0.0}
#: the context entry that each row's episode sets (:meth:`PolicyInterface.set_wind_readings`), not
#: its environment's configuration
READING_CONTEXT = "wind_reading"


def context_values(names: tuple[str, ...], env_config: Any) -> np.ndarray:
    """The context features ``names`` (:data:`CONTEXTS`) of one environment configuration.

    >>> from types import SimpleNamespace
    >>> context_values(("axis_encoders",), SimpleNamespace(encoders="axis")).tolist()
    [1.0]
    """
    return np.array([CONTEXTS[k](env_config) for k in names], np.float32)


def _entries(value: Any, name: str) -> tuple[int, ...]:
    """Distinct observation indices 0-11 (a clear error naming ``name`` otherwise)."""
    ok = isinstance(value, (list, tuple)) and len(value) > 0 and all(
        isinstance(i, (int, np.integer)) and not isinstance(i, bool) and 0 <= i < OBS_SIZE for i in value)
    if not ok or len(set(int(i) for i in value)) != len(value):
        raise ValueError(f"{name} must be distinct observation indices 0-11, got {value!r}")
    return tuple(int(i) for i in value)


def _lqg_features(feats: Any, base: str | None, estimate: bool) -> tuple[str, ...]:
    """Distinct names of :data:`LQG_FEATURE_WIDTHS`, command and disturbance only for the scheduled
    base (a clear error naming ``lqg_features`` otherwise).
    """
    if isinstance(feats, str) or not isinstance(feats, (list, tuple)) or not feats or \
            any(f not in LQG_FEATURE_WIDTHS for f in feats) or len(set(feats)) != len(feats):
        raise ValueError(f"lqg_features must be distinct names of {list(LQG_FEATURE_WIDTHS)}, "
                         f"got {feats!r}")
    if base == SCHEDULED_BASE and estimate is True and {"output", "law"} & set(feats):
        raise ValueError(f"lqg_features: base {SCHEDULED_BASE} gives the command and disturbance "
                         f"features only, got {list(feats)}")
    return tuple(feats)


@dataclass(frozen=True)
class InterfaceSpec:
    """What the policy sees and how its output becomes the environment action (module doc).

    :param base: ``None``, ``"pi"``, ``"lqg"``, ``"lqg_pointing"`` or ``"lqg_pointing_sched"``
    :param action: ``"absolute"`` or ``"residual"``
    :param gains: PI gain set of ``configs/model.yaml`` or ``(kp, ki)``, default ``"kp1"``
    :param residual_scale: action units per unit of policy output, default 0.05
    :param history: previous steps in the observation, default 0
    :param history_entries: observation entries kept in the history, default (0, 1, 10, 11)
    :param estimate: LQG base: add its features to the observation, default True
    :param lqg_features: which LQG features (:data:`LQG_FEATURE_WIDTHS`), default all four
    :param obs_entries: the environment's observation entries the policy sees, default None:
        all 12
    :param feedforward_gain: ``"feedforward"`` action: the commanded rate's gain, default 1.0
    :param action_curve: ``"feedforward"`` action: the curvature ``b`` of
        ``g(u) = sinh(b u) / sinh(b)``, 0 <= b <= 10, default 0: linear
    :param obs_symlog: the environment's entries (and their history) as symlog of mdeg and
        mdeg/s (:func:`symlog_observation`), default False: as the environment gives them
    :param history_filters: time constants (s, each in (0, 60]) of first-order low-pass
        filters of the ``history_entries``, appended after the history (symlog like them with
        ``obs_symlog``): memory of seconds in a few entries, from which a feed-forward network
        can form lead and lag; default none
    :param context: names of :data:`CONTEXTS` appended last (constants of the environment's
        configuration, e.g. ``["axis_encoders"]``, or the episode's ``"wind_reading"``); default
        none
    :param action_filter_s: time constant (s, in [0, 10]) of a first-order low-pass
        filter on the environment action the action map gives (base and residual together;
        an episode's first action passes unfiltered): smooth commands by construction, the
        filter's state part of the loop the policy sees through the applied rates; default 0:
        none
    """

    base: str | None = None
    action: str = "absolute"
    gains: Any = "kp1"
    residual_scale: float = 0.05
    history: int = 0
    history_entries: tuple[int, ...] = HISTORY_ENTRIES
    estimate: bool = True
    lqg_features: tuple[str, ...] = tuple(LQG_FEATURE_WIDTHS)
    obs_entries: tuple[int, ...] | None = None
    feedforward_gain: float = 1.0
    action_curve: float = 0.0
    obs_symlog: bool = False
    history_filters: tuple[float, ...] = ()
    context: tuple[str, ...] = ()
    action_filter_s: float = 0.0

    def __post_init__(self) -> None:
        if self.base not in BASES:
            raise ValueError(f"base must be null, 'pi', 'lqg', 'lqg_pointing' or 'lqg_pointing_sched', "
                             f"got {self.base!r}")
        if self.action not in ACTIONS:
            raise ValueError(f"action must be 'absolute', 'residual' or 'feedforward', got {self.action!r}")
        if self.action == "residual" and self.base is None:
            raise ValueError("a residual action needs a base controller (base: pi, lqg, lqg_pointing "
                             "or lqg_pointing_sched)")
        scale = self.residual_scale
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or \
                not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"residual_scale must be finite and > 0, got {scale!r}")
        h = self.history
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 0:
            raise ValueError(f"history must be an integer >= 0, got {h!r}")
        object.__setattr__(self, "history_entries", _entries(self.history_entries, "history_entries"))
        if self.obs_entries is not None:
            object.__setattr__(self, "obs_entries", _entries(self.obs_entries, "obs_entries"))
        object.__setattr__(self, "lqg_features", _lqg_features(self.lqg_features, self.base, self.estimate))
        taus = self.history_filters
        if isinstance(taus, (str, bytes)) or not isinstance(taus, (list, tuple)) or len(taus) > 8 or not all(
                isinstance(t, (int, float)) and not isinstance(t, bool) and 0.0 < t <= 60.0 for t in taus):
            raise ValueError(f"history_filters must be a list of at most 8 time constants in (0, 60] s, "
                             f"got {taus!r}")
        object.__setattr__(self, "history_filters", tuple(float(t) for t in taus))
        ctx = self.context
        if isinstance(ctx, (str, bytes)) or not isinstance(ctx, (list, tuple)) or \
                any(c not in CONTEXTS for c in ctx) or len(set(ctx)) != len(ctx):
            raise ValueError(f"context must be distinct names of {list(CONTEXTS)}, got {ctx!r}")
        object.__setattr__(self, "context", tuple(ctx))
        if not isinstance(self.obs_symlog, bool):
            raise ValueError(f"obs_symlog must be true or false, got {self.obs_symlog!r}")
        if not isinstance(self.estimate, bool):
            raise ValueError(f"estimate must be true or false, got {self.estimate!r}")
        object.__setattr__(self, "residual_scale", float(scale))
        for name, lo, hi in (("feedforward_gain", 0.0, 10.0), ("action_curve", 0.0, 10.0),
                             ("action_filter_s", 0.0, 10.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ValueError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        object.__setattr__(self, "history", int(h))
        if isinstance(self.gains, list):
            object.__setattr__(self, "gains", tuple(self.gains))

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["history_entries"] = list(self.history_entries)
        d["lqg_features"] = list(self.lqg_features)
        d["history_filters"] = list(self.history_filters)
        d["context"] = list(self.context)
        if self.obs_entries is not None:
            d["obs_entries"] = list(self.obs_entries)
        if isinstance(d["gains"], tuple):
            d["gains"] = list(d["gains"])
        return d


class _RecordingLQG(LQGController):
    """The baseline LQG, remembering the LQR state its law acted on (public ``law`` hook)."""

    def law(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        self.last_z, self.last_r_ss = z, r_ss
        return super().law(z, r_ss, r_prev)


#: number of LQG estimate features with every one of them (:meth:`PolicyInterface.observe`)
LQG_FEATURES = sum(LQG_FEATURE_WIDTHS.values())


class PolicyInterface:
    """Batched observation features and action map (see the module docstring).

    :param spec: the :class:`InterfaceSpec`
    :param env_config: the training environment's :class:`~dss14_env.envs.config.EnvConfig`
        (period, action scale, limits: what the base controllers are designed for)
    :param n: number of rows (sub-environments), default 1
    """

    def __init__(self, spec: InterfaceSpec, env_config: Any, n: int = 1) -> None:
        if "monopulse" in getattr(env_config, "sensors", ()):
            raise ValueError("sensors: the policy interfaces read the encoders' 12 observation entries only; "
                             "use DSS14-v0 (or a scenario id) for the monopulse sensor")
        self.spec, self.env_config, self.n = spec, env_config, int(n)
        self._inv_scale = 1.0 / (env_config.action_scale_deg_s * DEG)
        #: the observation's command rate (rate-limit units) in action units, times the gain
        self._ff = spec.feedforward_gain * env_config.rate_limit_deg_s / env_config.action_scale_deg_s
        self.command_rate = np.zeros((self.n, 2))
        self._symlog_units = symlog_units(env_config) if spec.obs_symlog else None
        self._err = env_config.error_scale_mdeg * MDEG
        self.pi: PIController | None = None
        self.lqg: list[_RecordingLQG] = []
        self.lqg_batch: LQGController | RowGroupedLQG | None = None
        n_feat = 0
        if spec.base == "pi":
            self.pi = PIController(env_config, spec.gains)
            n_feat = 2
        elif spec.base in LQG_BASES:
            n_feat = sum(LQG_FEATURE_WIDTHS[f] for f in spec.lqg_features) if spec.estimate else 0
            pointing = default_controllers_config().pointing if spec.base != "lqg" else None
            self._pointing = pointing
            if spec.estimate and {"output", "law"} & set(spec.lqg_features):
                # the LQR state z of every row: one recording controller per row
                self.lqg = [_RecordingLQG(env_config, pointing=pointing) for _ in range(self.n)]
            else:  # command and disturbance only: one batched LQG for all rows
                self.lqg_batch = batched_lqg(env_config, pointing, self.n, spec.base == SCHEDULED_BASE)
        #: where each row's base controller expects the encoders (:meth:`set_context`)
        self._base_encoders = [getattr(env_config, "encoders", None)] * self.n
        self.n_features = n_feat
        self.entries = list(range(OBS_SIZE)) if spec.obs_entries is None else list(spec.obs_entries)
        n_hist = len(spec.history_entries)
        self.obs_dim = (len(self.entries) + n_feat + (spec.history + len(spec.history_filters)) * n_hist
                        + len(spec.context))
        #: the context features of every row (:meth:`set_context`), from ``env_config`` until set
        self.context = np.tile(context_values(spec.context, env_config), (self.n, 1))
        #: the filters' gains per step, and their states (raw observation units)
        self._alpha = np.array([-math.expm1(-env_config.dt / t) for t in spec.history_filters])
        self._filt = np.zeros((self.n, len(spec.history_filters), n_hist), np.float64)
        self.base_action = np.zeros((self.n, 2))
        #: the action filter's gain per step (0: no filter), state and rows starting afresh
        self._act_alpha = -math.expm1(-env_config.dt / spec.action_filter_s) if spec.action_filter_s else 0.0
        self.filtered_action = np.zeros((self.n, 2))
        self._act_fresh = np.ones(self.n, bool)
        self._past = np.zeros((self.n, spec.history, len(spec.history_entries)), np.float32)
        self._fresh = np.ones(self.n, bool)
        #: each row's mean wind speed reading of its episode (m/s; NaN: none), and where the rows'
        #: readings come from at every (auto)reset (:meth:`restart`): ``rows -> speeds``, or None
        self.wind_readings = np.full(self.n, math.nan)
        self.wind_source: Callable[[np.ndarray], Any] | None = None

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Every row starts a new episode at its next :meth:`observe`."""
        self.restart(np.ones(self.n, bool))
        if self.pi is not None:
            self.pi.reset()

    def restart(self, mask: np.ndarray) -> None:
        """Rows ``mask`` (bool ``(n,)``) start new episodes at their next :meth:`observe`."""
        mask = np.asarray(mask, bool)
        if mask.shape != (self.n,):
            raise ValueError(f"restart mask must have shape ({self.n},), got {mask.shape}")
        self._fresh |= mask
        self._act_fresh |= mask
        if self.pi is not None:
            self.pi.restart(mask)
        if self.lqg_batch is not None:
            self.lqg_batch.restart(mask)
        for i in np.flatnonzero(mask).tolist():
            if self.lqg:
                self.lqg[i].reset()
        self.wind_readings[mask] = math.nan  # the ended episodes' readings
        self._reading_context()
        if self.wind_source is not None and mask.any():
            rows = np.flatnonzero(mask)
            self.set_wind_readings(self.wind_source(rows), rows)

    def set_wind_readings(self, wind_speeds: Any, rows: Sequence[int] | None = None) -> None:
        """The mean wind speed readings (m/s) of the episodes rows ``rows`` (default all) start
        next or have just started (before their first :meth:`observe`); a scheduled base
        (``lqg_pointing_sched``) designs each of those episodes for its reading.

        :raises ValueError: one line, unless one finite speed in 0..90 km/h per row
        """
        idx = np.arange(self.n) if rows is None else np.asarray(rows, int).reshape(-1)
        speeds = check_readings(wind_speeds, idx.size)
        self.wind_readings[idx] = speeds
        self._reading_context()
        if self.spec.base == SCHEDULED_BASE:
            self.lqg_batch.set_row_readings(idx, speeds)

    def _reading_context(self) -> None:
        """The ``wind_reading`` context entry of every row from its reading (0 without one)."""
        if READING_CONTEXT in self.spec.context:
            col = self.spec.context.index(READING_CONTEXT)
            self.context[:, col] = np.nan_to_num(self.wind_readings / MAX_READING, nan=0.0)

    #: the attributes of the dynamic state (:meth:`get_state`)
    _STATE = ("pi", "lqg", "lqg_batch", "_base_encoders", "base_action", "command_rate", "_past", "_filt",
              "_fresh", "filtered_action", "_act_fresh", "wind_readings", "context")

    def get_state(self) -> dict[str, Any]:
        """A copy of the dynamic state (base controllers, last base action, history) that
        :meth:`set_state` restores (the environment's snapshots hold it,
        :meth:`dss14_env.envs.env.DSS14Env.attach`), with the interface it belongs to.
        """
        state = copy.deepcopy({name: getattr(self, name) for name in self._STATE})
        return {"interface": self.spec.to_dict(), "n": self.n, **state}

    def check_state(self, state: Any) -> None:
        """That ``state`` is a :meth:`get_state` copy of an interface like this one (the same
        :class:`InterfaceSpec` and number of rows): a snapshot of another wrapper id is refused.

        :raises ValueError: one line naming what differs
        """
        if not isinstance(state, dict) or set(state) != {"interface", "n", *self._STATE}:
            raise ValueError("state must hold this environment's policy interface state (from "
                             "get_state()), got another object")
        if state["interface"] != self.spec.to_dict() or state["n"] != self.n:
            theirs = state["interface"] if isinstance(state["interface"], dict) else {}
            key = next((k for k, v in self.spec.to_dict().items() if theirs.get(k) != v), "n")
            raise ValueError(f"state must come from an environment with this policy interface: field "
                             f"{key!r} is {theirs.get(key, state['n'])!r} in the snapshot, "
                             f"{self.spec.to_dict().get(key, self.n)!r} here (another wrapper id?)")

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`get_state` copy (any number of times), checked first
        (:meth:`check_state`).
        """
        self.check_state(state)
        self.__dict__.update(copy.deepcopy({name: state[name] for name in self._STATE}))

    def set_context(self, env_configs: Any) -> None:
        """The environments the rows act on: one configuration for every row, or a sequence of
        ``n`` (a mixture's sub-environments). Sets the context features, and an LQG base is
        designed for each row's encoder placement (:func:`dss14_env.agents.base_rows.batched_base`;
        the interface's own configuration's design where they agree). A base redesigned here
        starts afresh: call it before the rows' episodes start.
        """
        if isinstance(env_configs, (list, tuple)):
            if len(env_configs) != self.n:
                raise ValueError(f"set_context: {len(env_configs)} configurations for {self.n} rows")
            configs = list(env_configs)
        else:
            configs = [env_configs] * self.n
        self.context = np.stack([context_values(self.spec.context, c) for c in configs])
        self._reading_context()
        encoders = [getattr(c, "encoders", None) for c in configs]
        if self.spec.base not in LQG_BASES or None in encoders or encoders == self._base_encoders:
            return
        self._base_encoders = encoders
        if self.lqg:
            self.lqg = [_RecordingLQG(dataclasses.replace(self.env_config, encoders=e),
                                      pointing=self._pointing) for e in encoders]
        else:
            self.lqg_batch = batched_base(self.env_config, self._pointing, encoders,
                                          self.spec.base == SCHEDULED_BASE)
            known = np.flatnonzero(np.isfinite(self.wind_readings))
            if known.size:  # the new base gets the readings given so far
                self.set_wind_readings(self.wind_readings[known], known)

    # ------------------------------------------------------------------ observation
    def observe(self, obs: np.ndarray) -> np.ndarray:
        """Advance every row on its environment observation; the policy's observations.

        :param obs: ``(n, 12)``
        :return: ``(n, obs_dim)`` float32
        """
        o = np.asarray(obs, np.float32)
        if o.shape != (self.n, OBS_SIZE):
            raise ValueError(f"observation must have shape ({self.n}, {OBS_SIZE}), got {o.shape}")
        seen = self._seen(o)
        parts = [seen[:, self.entries]]
        self.command_rate = o[:, OBS.command_rate].astype(np.float64)
        if self.pi is not None:
            self.base_action = self.pi.act(o).astype(np.float64)
            parts.append(self._pi_features(self.pi))
        elif self.lqg:
            feats = []
            for i, c in enumerate(self.lqg):
                self.base_action[i] = c.act(o[i])
                if self.spec.estimate:
                    feats.append(self._lqg_features(c, self.base_action[i]))
            if feats:
                parts.append(np.clip(np.asarray(feats), -FEATURE_BOUND, FEATURE_BOUND)
                             .astype(np.float32))
        elif self.lqg_batch is not None:
            self.base_action = self.lqg_batch.act_batch(o).astype(np.float64)
            if self.spec.estimate:
                parts.append(self._lqg_batch_features(self.lqg_batch, self.base_action,
                                                      np.arange(self.n)))
        if self.spec.history:
            now = seen[:, list(self.spec.history_entries)]
            parts.append(self._history(self._past, self._fresh, now))
            self._past = np.roll(self._past, 1, axis=1)
            self._past[:, 0] = now
        if self.spec.history_filters:
            self._filt = self._filtered(self._filt, self._fresh, o)
            parts.append(self._filter_part(self._filt))
        if self.spec.context:
            parts.append(self.context)
        self._fresh[:] = False
        return np.concatenate(parts, axis=1)

    def peek(self, obs: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The policy's observations of rows ``rows`` for observations ``obs``
        ``(len(rows), 12)``, without changing any state (a vector env's terminal
        observations): what :meth:`observe` would return for them.
        """
        rows = np.asarray(rows)
        o = np.asarray(obs, np.float32).reshape(rows.size, OBS_SIZE)
        seen = self._seen(o)
        parts = [seen[:, self.entries]]
        if self.pi is not None:
            pi = copy.deepcopy(self.pi)
            full = np.zeros((self.n, 12), np.float32)
            full[rows] = o
            pi.act(full)
            parts.append(self._pi_features(pi)[rows])
        elif self.lqg and self.spec.estimate:
            feats = []
            for k, i in enumerate(rows.tolist()):
                c = copy.deepcopy(self.lqg[i])
                feats.append(self._lqg_features(c, c.act(o[k])))
            parts.append(np.clip(np.asarray(feats), -FEATURE_BOUND, FEATURE_BOUND)
                         .astype(np.float32))
        elif self.lqg_batch is not None and self.spec.estimate:
            c = copy.deepcopy(self.lqg_batch)
            full = np.zeros((self.n, 12), np.float32)
            full[rows] = o
            action = c.act_batch(full).astype(np.float64)
            parts.append(self._lqg_batch_features(c, action[rows], rows))
        if self.spec.history:
            now = seen[:, list(self.spec.history_entries)]
            parts.append(self._history(self._past[rows].copy(), self._fresh[rows], now))
        if self.spec.history_filters:
            parts.append(self._filter_part(self._filtered(self._filt[rows], self._fresh[rows], o)))
        if self.spec.context:
            parts.append(self.context[rows])
        return np.concatenate(parts, axis=1)

    def _filtered(self, state: np.ndarray, fresh: np.ndarray, o: np.ndarray) -> np.ndarray:
        """The filters' next states for observations ``o`` (rows starting an episode start
        from their first observation, the steady state the episode starts in); a new array.
        """
        x = o[:, list(self.spec.history_entries)].astype(np.float64)[:, None, :]
        out = state + self._alpha[None, :, None] * (x - state)
        if fresh.any():
            out[fresh] = x[fresh]
        return out

    def _filter_part(self, state: np.ndarray) -> np.ndarray:
        """The filter states as the policy sees them (symlog like the history), flattened."""
        flat = state.astype(np.float32)
        if self._symlog_units is not None:
            units = self._symlog_units[list(self.spec.history_entries)]
            flat = symlog_observation(flat, units)
        return flat.reshape(flat.shape[0], -1)

    def _seen(self, o: np.ndarray) -> np.ndarray:
        """The environment's entries as the policy sees them (symlog or as given)."""
        return o if self._symlog_units is None else symlog_observation(o, self._symlog_units)

    @staticmethod
    def _history(past: np.ndarray, fresh: np.ndarray, now: np.ndarray) -> np.ndarray:
        """The history part (rows starting an episode repeat their first observation)."""
        if fresh.any():
            past[fresh] = now[fresh][:, None, :]
        return past.reshape(past.shape[0], -1).copy()

    @staticmethod
    def _pi_features(pi: PIController) -> np.ndarray:
        return np.clip(pi.integral_action(), -FEATURE_BOUND, FEATURE_BOUND).astype(np.float32)

    def _lqg_batch_features(self, c: LQGController | RowGroupedLQG, action: np.ndarray,
                            rows: np.ndarray) -> np.ndarray:
        """The command and disturbance features of rows ``rows`` of the batched LQG (``action``:
        those rows' commands).
        """
        parts = []
        for name in self.spec.lqg_features:
            if name == "command":
                parts.append(action)
            else:  # "disturbance"
                parts.append(np.array([c.disturbance(int(i)) for i in rows]) * self._inv_scale)
        return np.clip(np.concatenate(parts, axis=1), -FEATURE_BOUND, FEATURE_BOUND).astype(np.float32)

    def _lqg_features(self, c: _RecordingLQG, action: np.ndarray) -> np.ndarray:
        """The chosen features of the LQG's estimate (``spec.lqg_features``, at most 12), whose
        meaning does not depend on its design (the design, and with it the order of the Kalman
        filter, may change per episode).
        """
        n = c.design.dm.n
        z = c.last_z
        dx = z[:n]
        parts = []
        for name in self.spec.lqg_features:
            if name == "command":
                parts.append(action)
            elif name == "disturbance":
                parts.append(c.disturbance() * self._inv_scale)
            elif name == "output":
                parts.append((c.design.dm.C @ dx) / self._err)
            else:  # "law": the three terms of the LQR law
                terms = [c.Kx @ dx, c.Ki @ z[n:n + 2] if c.design.integral else np.zeros(2),
                         c.Ku @ z[-2:]]
                parts += [t * self._inv_scale for t in terms]
        return np.concatenate(parts)

    # ------------------------------------------------------------------ action
    def action(self, u: np.ndarray) -> np.ndarray:
        """Environment actions ``(n, 2)`` for the policy outputs ``u`` ``(n, 2)`` at the last
        observed step (training environment's action units), clipped to [-1, 1].

        :raises ValueError: wrong shape or non-finite output
        """
        u = np.asarray(u, np.float64)
        if u.shape != (self.n, 2) or not np.all(np.isfinite(u)):
            raise ValueError(f"policy output must be finite with shape ({self.n}, 2), got "
                             f"shape {u.shape}")
        u = np.clip(u, -1.0, 1.0)
        if self.spec.action == "absolute":
            a = u
        elif self.spec.action == "residual":
            a = self.base_action + self.spec.residual_scale * u
        else:
            a = self._ff * self.command_rate + self.spec.residual_scale * action_curve(
                u, self.spec.action_curve)
        a = np.clip(a, -1.0, 1.0)
        if self._act_alpha:
            prev = np.where(self._act_fresh[:, None], a, self.filtered_action)
            a = self.filtered_action = prev + self._act_alpha * (a - prev)
            self._act_fresh[:] = False
        return a.astype(np.float32)


def symlog_units(env_config: Any) -> np.ndarray:
    """Millidegrees (or per second) per unit of each of the 12 observation entries: errors and error rates
    in ``error_scale_mdeg``, command and encoder angles in deg, rates in ``rate_limit_deg_s``.
    """
    u = np.empty(OBS_SIZE, np.float32)
    u[OBS.error] = u[OBS.error_rate] = env_config.error_scale_mdeg
    u[OBS.command] = u[OBS.encoder] = 1.0e3
    u[OBS.command_rate] = u[OBS.prev_rate] = env_config.rate_limit_deg_s * 1.0e3
    return u


def symlog_observation(obs: np.ndarray, units: np.ndarray) -> np.ndarray:
    """``sign(x) log(1 + |x|)`` of the observation in mdeg and mdeg/s (``units``:
    :func:`symlog_units`), float32: linear below about 1 mdeg, logarithmic above.

    >>> symlog_observation(np.array([[0.1, -10.0]], np.float32), np.array([10.0, 10.0], np.float32)).round(3)
    array([[ 0.693, -4.615]], dtype=float32)
    """
    x = obs * units
    return (np.sign(x) * np.log1p(np.abs(x))).astype(np.float32)


def action_curve(u: np.ndarray, b: float) -> np.ndarray:
    """``sinh(b u) / sinh(b)`` (``u`` itself for ``b = 0``): odd, 0 at 0, +-1 at +-1, slope
    ``b / sinh(b)`` at 0.

    >>> action_curve(np.array([-1.0, 0.0, 0.5, 1.0]), 4.0).round(4).tolist()
    [-1.0, 0.0, 0.1329, 1.0]
    """
    return u if b == 0.0 else np.sinh(b * u) / math.sinh(b)


# ---------------------------------------------------------------------------- Gymnasium face
class InterfaceWrapper(gym.Wrapper):
    """A DSS14 environment seen through a :class:`PolicyInterface` (N = 1).

    Action ``Box(-1, 1, (2,))`` (the policy output), observation ``Box((obs_dim,))``;
    reward, termination and info are the environment's.

    :param env: a DSS14 environment (``gymnasium.make("DSS14-Hold-v0")`` etc.)
    :param spec: the interface
    """

    def __init__(self, env: gym.Env, spec: InterfaceSpec) -> None:
        super().__init__(env)
        cfg = env.unwrapped.config
        self.interface = PolicyInterface(spec, cfg, 1)
        if hasattr(env.unwrapped, "attach"):  # its snapshots restore the interface too
            env.unwrapped.attach(self.interface)
        self.observation_space = interface_observation_space(self.interface)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.interface.reset()
        if "wind_speed_mps" in info:  # the episode's mean wind speed reading
            self.interface.set_wind_readings([info["wind_speed_mps"]])
        return self.interface.observe(obs[None])[0], info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        a = self.interface.action(as_actions(action, (2,))[None])[0]
        obs, reward, terminated, truncated, info = self.env.step(a)
        return self.interface.observe(obs[None])[0], reward, terminated, truncated, info


def interface_observation_space(interface: PolicyInterface) -> spaces.Box:
    """The policy's observation space (bounds of the environment's entries, then features)."""
    s = interface.spec
    env_high = OBS_HIGH if not s.obs_symlog else symlog_observation(
        OBS_HIGH[None], symlog_units(interface.env_config))[0]
    high = np.concatenate([env_high[interface.entries],
                           np.full(interface.n_features, FEATURE_BOUND, np.float32),
                           np.tile(env_high[list(s.history_entries)], s.history + len(s.history_filters)),
                           np.ones(len(s.context), np.float32)]).astype(np.float32)
    return spaces.Box(-high, high, dtype=np.float32)


def spec_from_kwargs(kwargs: dict[str, Any], defaults: InterfaceSpec) -> tuple[InterfaceSpec, dict]:
    """``(spec, remaining env kwargs)``: interface keys taken out of wrapper-id kwargs."""
    kw = dict(kwargs)
    fields = {f.name for f in dataclasses.fields(InterfaceSpec)}
    given = {k: kw.pop(k) for k in list(kw) if k in fields}
    d = defaults.to_dict()
    d.update(given)
    return InterfaceSpec(**d), kw


__all__ = ["ACTIONS", "BASES", "CONTEXTS", "FEATURE_BOUND", "HISTORY_ENTRIES", "LQG_BASES", "READING_CONTEXT",
           "SCHEDULED_BASE",
           "InterfaceSpec",
           "InterfaceWrapper", "LQG_FEATURES", "LQG_FEATURE_WIDTHS", "NO_ABSOLUTE_ANGLES",
           "PolicyInterface", "action_curve", "context_values", "interface_observation_space",
           "spec_from_kwargs",
           "symlog_observation", "symlog_units"]

