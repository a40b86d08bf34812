"""``DSS14-v0``: the DSS-14 70-m antenna servo in gusty wind as a Gymnasium environment.

See :class:`DSS14Env` (the user manual, also in ``docs/env.md``).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dss14_env.envs.render import Renderer
from dss14_env.envs.scenarios import (
    DEG,
    MDEG,
    NOISE_BLOCK,
    EnvConfig,
    Episode,
    block_rows,
    command,
    draw_episode,
    draw_noise_block,
    load_env_config,
)

R2D = 180.0 / math.pi  # rad -> deg
R2MD = 180.0e3 / math.pi  # rad -> mdeg
#: bounds of the observation (see the table in DSS14Env); errors are clamped to them, which
#: can only happen on a terminating step
OBS_ERROR_BOUND = 1.0e4
OBS_ERROR_RATE_BOUND = 1.0e6
OBS_POSITION_BOUND_DEG = 720.0
OBS_HIGH = np.array([OBS_ERROR_BOUND] * 2 + [OBS_ERROR_RATE_BOUND] * 2 + [OBS_POSITION_BOUND_DEG] * 2
                    + [1.0] * 2 + [OBS_POSITION_BOUND_DEG] * 2 + [1.0] * 2, dtype=np.float32)
#: observation names, in order
OBS_NAMES = ("error_az", "error_el", "error_rate_az", "error_rate_el", "command_az", "command_el",
             "command_rate_az", "command_rate_el", "encoder_az", "encoder_el",
             "prev_rate_az", "prev_rate_el")
_N_OUT = 4  # outputs computed every step: OUTPUTS[:4] (encoders, pointing); gust torques on demand
_dot, _array, _f32, _floor = np.dot, np.array, np.float32, math.floor  # hot-path aliases


def _clamp(x: float, b: float) -> float:
    return b if x > b else (-b if x < -b else x)


class DSS14Env(gym.Env[np.ndarray, np.ndarray]):
    """The DSS-14 70-m antenna's closed rate loop in gusty wind, driven by rate commands.

    ## Description

    The plant is the calibrated linear model of JPL TDA Progress Report 42-124 (Gawronski &
    Bartos 1996): the closed rate loop of Eq. 56 (hydraulic drives, gearboxes, 2 rigid + 22
    flexible structural modes; 60 states) for azimuth and elevation, driven by Davenport wind
    gusts through a 4-state shaping filter (:mod:`dss14_env.wind.loads`, calibrated to the
    report's Table 4).  The agent plays the computer-mode position controller: every control
    period (``dt`` = 0.02 s) it sets the two axis rate commands and sees what that controller
    sees -- the encoder readings and the commanded trajectory.  The rate commands are held over
    the period (zero-order hold) and the plant is discretised exactly (matrix exponential; Van
    Loan for the gust noise; :mod:`dss14_env.envs.plant`), so the physics does not depend on ``dt``.
    Units: SI inside, degrees / millidegrees at the interface.

    ## Action space

    ``Box(-1, 1, (2,), float32)``: the requested azimuth and elevation rate commands in units of
    ``action_scale_deg_s`` (default 0.25 deg/s, so the full tracking rate is reachable and
    1e-4 of the range is 2.5e-5 deg/s, fine enough for wind rejection).  The command limiter
    then applies, in this order: clip to [-1, 1]; scale; clip to +-``rate_limit_deg_s``
    (0.25 deg/s); limit the change per step to ``accel_limit_deg_s2 * dt`` (0.2 deg/s^2 x
    0.02 s = 0.004 deg/s).  A NaN/inf action or one of another shape raises ``ValueError``.

    | index | action                  | unit at 1 |
    |-------|-------------------------|-----------|
    | 0     | azimuth rate command    | ``action_scale_deg_s`` |
    | 1     | elevation rate command  | ``action_scale_deg_s`` |

    ## Observation space

    ``Box(float32, (12,))``, nothing hidden: encoder readings, the commanded trajectory and what
    follows from them.  The encoders read the absolute angle (start + motion) rounded to the
    nearest count of ``encoder_bits`` per turn (20: 2 pi / 2^20 rad = 0.343 mdeg; ``None`` =
    exact) plus optional white Gaussian noise (``encoder_noise_mdeg``, default 0).  Servo error
    ``e = c - theta_measured`` in axis angle.

    | index  | observation                                              | unit |
    |--------|----------------------------------------------------------|------|
    | 0, 1   | servo error az, el                                       | ``error_scale_mdeg`` (10 mdeg) |
    | 2, 3   | servo-error rate ``(e[k] - e[k-1]) / dt``, az, el        | ``error_scale_mdeg`` per s |
    | 4, 5   | commanded position relative to the episode start, az, el | deg |
    | 6, 7   | commanded rate, az, el                                   | ``rate_limit_deg_s`` |
    | 8, 9   | encoder reading relative to the start position, az, el   | deg |
    | 10, 11 | previous applied rate command (limiter output), az, el   | ``rate_limit_deg_s`` |

    Bounds: +-1e4 (0, 1), +-1e6 (2, 3), +-720 (4, 5, 8, 9), +-1 (6, 7, 10, 11); entries 0-3
    are clamped to them, which can only act on a terminating step (or with encoder noise).
    At reset, entries 2, 3 are 0.

    ## Reward

    ``r = -( (e_az^2 + e_el^2) / error_scale_mdeg^2 + action_change_weight * ||a[k] - a[k-1]||^2 )``

    with ``e`` the *true* (unquantised) servo errors in mdeg at the end of the step and ``a``
    the action clipped to [-1, 1] (``a[-1]`` is the action that reproduces the start rate
    command).  Quadratic on purpose: a linear-quadratic yardstick applies to exactly this cost.
    Typical values: -0.01 per step for a PI in 50 km/h wind (about 1 mdeg rms).  The step that
    terminates costs ``termination_penalty`` (1e4, one step at the 1-deg error bound) more.

    ## Starting state

    The absolute start position is drawn (az uniform in [-200, 200] deg about the wrap centre,
    el in [20, 70] deg) or set (``start_az_deg``, ``start_el_deg``).  The antenna is already
    servoing: the rate loop is in the steady motion that follows the command's initial rate
    under the wind torque at t = 0 (mean plus the initial gust), the gust filter is in its
    stationary distribution, and the previous applied rate command (observation 10, 11) is the
    one that holds that motion.  A PI that starts bumplessly from it
    (:class:`dss14_env.baselines.pi.PIController`) has no start transient to discard.

    ## Episode end

    ``terminated`` when the true servo error exceeds ``max_error_deg`` (1 deg) on either axis
    or the antenna leaves its travel (elevation 6-88 deg, azimuth +-265 deg about the wrap
    centre).  ``truncated`` by the registered ``TimeLimit`` (``max_episode_steps``; steps, so
    pass ``max_episode_steps=`` to ``gymnasium.make`` with another ``dt``).

    ## Info

    Every step: ``servo_error_az_mdeg``, ``servo_error_el_mdeg`` (true), ``measured_error_*``
    (from the encoder readings), ``pointing_error_el_mdeg``, ``pointing_error_xel_mdeg`` (true
    elevation / cross-elevation pointing error of the dish: structure outputs, including its
    deformation), ``wind_speed_mps``, ``wind_direction_rad`` (the episode's mean wind),
    ``action_unclipped`` (the action as given, a tuple), ``rate_command_az_deg_s``,
    ``rate_command_el_deg_s`` (applied), ``rate_limited``, ``accel_limited`` (limiter flags),
    ``n_rate_limited``, ``n_accel_limited`` (the episode's limit-hit counts, also attributes of
    the unwrapped environment); with ``info_state=True`` also ``plant_state`` (balanced
    coordinates of the 68-state joint plant).  The reset info adds the scenario, start
    position and hydraulic parameters.  The instantaneous gust: :meth:`wind_gust`.

    ## Scenarios (``scenario``)

    * ``hold``: constant command in wind.
    * ``step``: command step of ``step_deg`` (0.1 deg) at ``step_time_s`` (1 s) on
      ``step_axes`` ([R] Fig. 21 shape); at 0.1 deg the acceleration limit acts on a PI.
    * ``track``: per axis ``v t + A (sin(w t + phi) - sin phi)`` with ``|v| <= 0.01 deg/s``,
      ``A <= 0.25 deg``, period 120-600 s, random phase (rates <= 0.023 deg/s, accelerations
      <= 7e-4 deg/s^2).
    * ``slew``: a trapezoidal-rate move of ``slew_deg`` (5 deg, random sign per axis) at
      0.15 deg/s and 0.1 deg/s^2, starting at 1 s.

    Wind: ``wind_speed_kmh`` (>= 0 or ``"random"`` from ``wind_speed_grid_kmh``) and
    ``wind_direction`` relative to the dish (``"front"``, ``"side"``, rad, or ``"random"`` from
    ``wind_direction_grid_deg``), fixed per episode.

    ## Arguments

    ``gymnasium.make("DSS14-v0", render_mode=None, config=None, **keys)``: ``config`` is a YAML
    file or mapping of keys (default ``configs/env.yaml``); ``keys`` override single keys (e.g.
    ``dt=0.01``, ``encoder_bits=None``, ``wind_speed_kmh=50``).  Episode keys can change per
    reset: ``reset(options={"wind_speed_kmh": 70, "wind_direction": "side"})``.
    ``randomize_params=True`` draws the hydraulic parameters over the report's ranges (stable
    part) at every reset.  Bad values raise ``ValueError`` naming the key.

    ## Registered variants

    | id | scenario | wind | ``max_episode_steps`` |
    |----|----------|------|-----------------------|
    | ``DSS14-v0`` | track | 30-70 km/h (step 10), 8 directions, drawn per episode | 3000 (60 s) |
    | ``DSS14-Hold-v0`` | hold | 50 km/h, front or side | 3000 (60 s) |
    | ``DSS14-Step-v0`` | step 0.1 deg, both axes | none | 2000 (40 s) |
    | ``DSS14-Slew-v0`` | slew 5 deg | 30 km/h, 8 directions | 3000 (60 s) |

    Vector version: ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
    (:class:`dss14_env.envs.vector.DSS14VectorEnv`).

    ## Version history

    * v0: initial version.

    :param render_mode: None, ``"rgb_array"`` or ``"human"``
    :param config: YAML path, mapping or :class:`~dss14_env.envs.scenarios.EnvConfig`, default the
        shipped ``configs/env.yaml``
    :param overrides: configuration keys
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    def __init__(self, render_mode: str | None = None,
                 config: str | EnvConfig | dict | None = None, **overrides: Any) -> None:
        super().__init__()
        self.config = load_env_config(config, **overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        self.render_mode = render_mode
        c = self.config
        self.metadata = dict(self.metadata, render_fps=1.0 / c.dt)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = spaces.Box(-OBS_HIGH, OBS_HIGH, dtype=np.float32)
        self._set_constants(c)
        self._renderer = Renderer(render_mode, c.dt, c.render_window_s) if render_mode else None
        self.episode: Episode | None = None
        self._st = None

    def _set_constants(self, c: EnvConfig) -> None:
        self._dt = c.dt
        self._inv_dt = 1.0 / c.dt
        self._scale = c.action_scale_deg_s * DEG
        self._rl = c.rate_limit_deg_s * DEG
        self._inv_rl = 1.0 / self._rl
        self._dr = c.accel_limit_deg_s2 * DEG * c.dt
        self._inv_es = 1.0 / c.error_scale_mdeg
        self._inv_es2 = self._inv_es * self._inv_es
        self._rate_scale = self._inv_es * self._inv_dt
        self._rate_clip = self._scale > self._rl
        self._w = c.action_change_weight
        self._q = (2.0 * math.pi / 2 ** c.encoder_bits) if c.encoder_bits else 0.0
        self._inv_q = 1.0 / self._q if self._q else 0.0
        self._sig = c.encoder_noise_mdeg * MDEG
        self._el_lo, self._el_hi = (v * DEG for v in c.el_limits_deg)
        self._az_c, self._az_h = c.az_wrap_centre_deg * DEG, c.az_wrap_half_range_deg * DEG
        self._cst = (self._scale, self._rate_clip, self._rl, self._dr, self._sig, self._q, self._inv_q,
                     self._inv_es, self._inv_rl, self._rate_scale, self._inv_es2, self._w, self._el_lo,
                     self._el_hi, self._az_h)

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode.

        :param seed: seed of ``self.np_random`` (the only source of randomness)
        :param options: episode keys for this episode only (``EPISODE_KEYS`` of
            :mod:`dss14_env.envs.scenarios`), e.g. ``{"scenario": "hold", "wind_speed_kmh": 50}``
        :return: observation and info
        """
        super().reset(seed=seed)
        cfg = self.config.with_options(options)
        ep = draw_episode(cfg, self.np_random)
        self.episode = ep
        p = ep.plant
        k = p.noise_rank
        # the episode's one-copy (64-state) form of the plant: exact, see Plant.one_copy_projection
        Tm, Pm = p.one_copy_projection(ep.kappa)
        n = Pm.shape[0]
        h = 3 + k  # z = [r_a, r_e, 1, xi (k), x (n), y (m)]
        # fused one-step map: [x+, y+] = M z, the noise entering through xi
        Ad, Bd, C = Pm @ p.Ad @ Tm, Pm @ np.hstack([p.Bd_r, (p.Bd_T @ ep.t_mean)[:, None]]), p.C @ Tm
        L = Pm @ p.noise_matrix(ep.kappa)
        M = np.zeros((n + _N_OUT, h + n))
        M[:n, :3], M[:n, 3:h], M[:n, h:] = Bd, L, Ad
        M[n:] = C[:_N_OUT] @ M[:n]
        x0 = Pm @ ep.x0
        self._state_map, self._C_gust = Tm, C[_N_OUT:]
        r0 = np.clip(ep.r0, -self._rl, self._rl)
        z0, z1 = np.zeros(h + n + _N_OUT), np.zeros(h + n + _N_OUT)
        z0[:2], z0[2], z0[h:h + n], z0[h + n:] = r0, 1.0, x0, C[:_N_OUT] @ x0
        z1[2] = 1.0
        # per buffer: (z, z without y, [x, y], y); the current one first
        bufs = tuple((z, z[:h + n], z[h:], z[h + n:]) for z in (z0, z1))
        # encoder noise of the reading at t = 0, then the first noise block (this order)
        ne = (self.np_random.standard_normal(2) * self._sig).tolist() if self._sig else (0.0, 0.0)
        self._rank, self._n = k, n
        self._next_block(0)
        s_az, s_el = float(ep.start[0]), float(ep.start[1])
        rp0, rp1 = float(r0[0]), float(r0[1])
        me = cfg.max_error_deg * DEG * R2MD
        q_mdeg = self._q * R2MD
        # without encoder noise the observation bounds can only be passed on a terminating step
        clamp_always = bool(self._sig) or (me + q_mdeg) * self._inv_es > OBS_ERROR_BOUND or \
            2.0 * (me + q_mdeg) * self._rate_scale > OBS_ERROR_RATE_BOUND
        self._gust_az, self._gust_inv = gust_divisor(ep.kappa, p.g0)
        # everything step() reads that is fixed for the episode, in one tuple
        self._ep = self._cst + (M, k, s_az, s_el, me, s_az - self._az_c, cfg.termination_penalty,
                                ep.wind_speed, ep.wind_direction, cfg.info_state, n, clamp_always)
        enc_az, enc_el, p_el, p_xel = bufs[0][3].tolist()
        (c_az, c_el), (cd_az, cd_el) = (v[0].tolist() for v in command(ep.traj, np.zeros(1)))
        em_az, enc_rel_az = self._measure(c_az, enc_az, s_az, ne[0])
        em_el, enc_rel_el = self._measure(c_el, enc_el, s_el, ne[1])
        self._st = (bufs, rp0, rp1, rp0 / self._scale, rp1 / self._scale, em_az, em_el, 0, 0, 0)
        ib = self._inv_es
        obs = np.array((_clamp(em_az * ib, OBS_ERROR_BOUND), _clamp(em_el * ib, OBS_ERROR_BOUND), 0.0, 0.0,
                        c_az * R2D, c_el * R2D, cd_az * self._inv_rl, cd_el * self._inv_rl,
                        enc_rel_az * R2D, enc_rel_el * R2D, rp0 * self._inv_rl, rp1 * self._inv_rl),
                       dtype=np.float32)
        e_az, e_el = (c_az - enc_az) * R2MD, (c_el - enc_el) * R2MD
        gust = self._gust_of(x0)
        info = {"scenario": cfg.scenario, "start_az_deg": s_az * R2D, "start_el_deg": s_el * R2D,
                "wind_speed_mps": ep.wind_speed, "wind_direction_rad": ep.wind_direction,
                "params": dict(ep.params),
                "servo_error_az_mdeg": e_az, "servo_error_el_mdeg": e_el,
                "measured_error_az_mdeg": em_az, "measured_error_el_mdeg": em_el,
                "pointing_error_el_mdeg": p_el * R2MD, "pointing_error_xel_mdeg": p_xel * R2MD,
                "rate_command_az_deg_s": rp0 * R2D, "rate_command_el_deg_s": rp1 * R2D}
        if cfg.info_state:
            info["plant_state"] = ep.x0.copy()
        if self._renderer is not None:
            self._renderer.reset(f"{cfg.scenario}, wind {ep.wind_speed * 3.6:.0f} km/h at "
                                 f"{ep.wind_direction * R2D:.0f} deg")
            self._renderer.record(0.0, e_az, e_el, rp0 * R2D, rp1 * R2D, cd_az * R2D, cd_el * R2D,
                                  ep.wind_speed + gust)
            if self.render_mode == "human":
                self._renderer.show()
        return obs, info

    def _measure(self, c: float, theta: float, start: float, noise: float) -> tuple[float, float]:
        """Measured servo error (mdeg) and encoder reading relative to the start (rad)."""
        a = start + theta + noise
        if self._q:
            a = self._q * math.floor(a * self._inv_q + 0.5)
        rel = a - start
        return (c - rel) * R2MD, rel

    def _next_block(self, k0: int) -> None:
        """Per-step rows of steps ``k0 .. k0 + NOISE_BLOCK - 1``: ``(c_az, c_el, c_az_deg,
        c_el_deg, cd_az / rate_limit, cd_el / rate_limit, xi_1..xi_k, noise_az, noise_el)``: the
        command at the step's end ``t[k+1]`` (rad, deg, scaled rate), the step's standard
        normals and the encoder noise in rad (:func:`dss14_env.envs.scenarios.block_rows`)."""
        blk = draw_noise_block(self.np_random, self._rank, self._sig > 0.0)
        self._rows = block_rows(self.episode.traj, k0, self._dt, self._rl, blk, self._sig).tolist()
        self._k0 = k0

    def wind_gust(self) -> float:
        """The current gust speed about the mean wind speed, m/s (0 without wind).

        Read from the gust torque of the axis with the larger direction factor.
        """
        if self._st is None:
            raise RuntimeError("call reset() before wind_gust()")
        return self._gust_of(self._st[0][0][2][:self._n])

    def _gust_of(self, x: np.ndarray) -> float:
        tg = self._C_gust @ x  # x: the episode's one-copy state
        return float(tg[0] if self._gust_az else tg[1]) * self._gust_inv

    @property
    def elapsed_steps(self) -> int:
        """Steps taken in the current episode."""
        return self._k0 + self._st[7]

    @property
    def n_rate_limited(self) -> int:
        """Steps of the current episode in which the rate clip acted."""
        return self._st[8] if self._st is not None else 0

    @property
    def n_accel_limited(self) -> int:
        """Steps of the current episode in which the acceleration limit acted."""
        return self._st[9] if self._st is not None else 0

    # ------------------------------------------------------------------ step
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply one rate command for one control period.

        :param action: shape ``(2,)``, finite (values beyond [-1, 1] are clipped)
        :return: observation, reward, terminated, truncated, info
        :raises ValueError: on a NaN/inf action or one of the wrong shape
        """
        try:  # fast path: a float ndarray of shape (2,)
            a0, a1 = action.tolist()
            fast = type(a0) is float and type(a1) is float
        except (AttributeError, TypeError, ValueError):
            fast = False
        if not fast:
            a0, a1 = _coerce_action(action)
        if not (a0 - a0 == 0.0 and a1 - a1 == 0.0):  # x - x is NaN for NaN and +-inf
            raise ValueError(f"action must be finite, got {[a0, a1]}")
        st = self._st
        if st is None:
            raise RuntimeError("call reset() before step()")
        (cur, nxt), rp0, rp1, ap0, ap1, em0, em1, j, n_rate, n_acc = st
        scale, rate_clip, rl, dr, sig, q, iq, ib, ir, rb, ies2, w, el_lo, el_hi, az_h, \
            M, rank, s_az, s_el, me, az_off0, penalty, wspeed, wdir, info_state, n, clamp_always = self._ep
        # ---- command limiter: box, rate clip, acceleration limit
        c0 = 1.0 if a0 > 1.0 else (-1.0 if a0 < -1.0 else a0)
        c1 = 1.0 if a1 > 1.0 else (-1.0 if a1 < -1.0 else a1)
        q0 = c0 * scale
        q1 = c1 * scale
        rate_hit = False
        if rate_clip:  # only if action_scale > rate_limit
            if q0 > rl or q0 < -rl or q1 > rl or q1 < -rl:
                rate_hit = True
                q0 = rl if q0 > rl else (-rl if q0 < -rl else q0)
                q1 = rl if q1 > rl else (-rl if q1 < -rl else q1)
        acc_hit = False
        b = rp0 + dr
        if q0 > b:
            q0, acc_hit = b, True
        else:
            b = rp0 - dr
            if q0 < b:
                q0, acc_hit = b, True
        b = rp1 + dr
        if q1 > b:
            q1, acc_hit = b, True
        else:
            b = rp1 - dr
            if q1 < b:
                q1, acc_hit = b, True
        # ---- plant: [x+, y+] = M [r, 1, xi, x, y]
        if j == NOISE_BLOCK:
            self._next_block(self._k0 + j)
            j = 0
        z0 = cur[0]
        z0[0] = q0
        z0[1] = q1
        if rank == 4:
            c_az, c_el, o4, o5, o6, o7, x1, x2, x3, x4, n_az, n_el = self._rows[j]
            z0[3] = x1
            z0[4] = x2
            z0[5] = x3
            z0[6] = x4
        else:
            row = self._rows[j]
            c_az, c_el, o4, o5, o6, o7, n_az, n_el = row[:6] + row[-2:]
            z0[3:3 + rank] = row[6:6 + rank]
        v1 = nxt[2]
        _dot(M, cur[1], v1)
        enc_az, enc_el, p_el, p_xel = nxt[3].tolist()
        # ---- command and measurement at t[k+1]
        if sig:
            a_az, a_el = s_az + enc_az + n_az, s_el + enc_el + n_el
        else:
            a_az, a_el = s_az + enc_az, s_el + enc_el
        if q:
            a_az = q * _floor(a_az * iq + 0.5)
            a_el = q * _floor(a_el * iq + 0.5)
        rel_az, rel_el = a_az - s_az, a_el - s_el
        em_az, em_el = (c_az - rel_az) * R2MD, (c_el - rel_el) * R2MD
        e_az, e_el = (c_az - enc_az) * R2MD, (c_el - enc_el) * R2MD
        # ---- episode end and reward
        el_abs = s_el + enc_el
        az_off = az_off0 + enc_az
        terminated = (e_az > me or e_az < -me or e_el > me or e_el < -me or el_abs < el_lo
                      or el_abs > el_hi or az_off > az_h or az_off < -az_h)
        d0, d1 = c0 - ap0, c1 - ap1
        cost = (e_az * e_az + e_el * e_el) * ies2 + w * (d0 * d0 + d1 * d1)
        if terminated:
            cost += penalty
        # ---- observation
        o0, o1 = em_az * ib, em_el * ib
        o2, o3 = (em_az - em0) * rb, (em_el - em1) * rb
        if terminated or clamp_always:
            o0, o1 = _clamp(o0, OBS_ERROR_BOUND), _clamp(o1, OBS_ERROR_BOUND)
            o2, o3 = _clamp(o2, OBS_ERROR_RATE_BOUND), _clamp(o3, OBS_ERROR_RATE_BOUND)
        obs = _array((o0, o1, o2, o3, o4, o5, o6, o7, rel_az * R2D, rel_el * R2D, q0 * ir, q1 * ir), _f32)
        if rate_hit:
            n_rate += 1
        if acc_hit:
            n_acc += 1
        self._st = ((nxt, cur), q0, q1, c0, c1, em_az, em_el, j + 1, n_rate, n_acc)
        info = {"servo_error_az_mdeg": e_az, "servo_error_el_mdeg": e_el,
                "measured_error_az_mdeg": em_az, "measured_error_el_mdeg": em_el,
                "pointing_error_el_mdeg": p_el * R2MD, "pointing_error_xel_mdeg": p_xel * R2MD,
                "wind_speed_mps": wspeed, "wind_direction_rad": wdir, "action_unclipped": (a0, a1),
                "rate_command_az_deg_s": q0 * R2D, "rate_command_el_deg_s": q1 * R2D,
                "rate_limited": rate_hit, "accel_limited": acc_hit,
                "n_rate_limited": n_rate, "n_accel_limited": n_acc}
        if info_state:
            info["plant_state"] = self._state_map @ v1[:n]
        if self._renderer is not None:
            self._renderer.record((self._k0 + j + 1) * self._dt, e_az, e_el, q0 * R2D, q1 * R2D,
                                  o6 * rl * R2D, o7 * rl * R2D, wspeed + self._gust_of(v1[:n]))
            if self.render_mode == "human":
                self._renderer.show()
        return obs, -cost, terminated, False, info

    # ------------------------------------------------------------------ rendering
    def render(self) -> np.ndarray | None:
        """``rgb_array``: the plot of recent servo errors, rate commands and wind as an
        ``(480, 640, 3)`` uint8 array; ``human``: redraw the window (returns None)."""
        if self._renderer is None:
            gym.logger.warn("render() called without a render_mode; use render_mode='rgb_array' or 'human'")
            return None
        if self.render_mode == "rgb_array":
            return self._renderer.rgb()
        self._renderer.show()
        return None

    def close(self) -> None:
        """Close the render window, if any."""
        if self._renderer is not None:
            self._renderer.close()


def gust_divisor(kappa: np.ndarray, g0: float) -> tuple[bool, float]:
    """``(use_az, 1 / (kappa_axis g0))``: gust speed = gust torque of that axis times the factor
    (the axis with the larger direction factor; factor 0 without wind)."""
    k0, k1 = float(kappa[0]), float(kappa[1])
    use_az = abs(k0) >= abs(k1)
    k = k0 if use_az else k1
    return use_az, (1.0 / (k * g0) if k != 0.0 and g0 != 0.0 else 0.0)


def _coerce_action(action: Any) -> tuple[float, float]:
    """Two floats from an array-like action (``ValueError`` on a bad shape or type)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action must be a numeric array of shape (2,), got {action!r}") from exc
    if a.shape != (2,):
        raise ValueError(f"action must have shape (2,), got shape {a.shape}")
    a0, a1 = a.tolist()
    return a0, a1
