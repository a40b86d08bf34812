"""numpy-batched vector version of :class:`dss14_env.envs.env.DSS14Env`.

``gymnasium.make_vec("DSS14-v0", num_envs=N, vectorization_mode="vector_entry_point")`` builds
:class:`DSS14VectorEnv`.  All N sub-environments advance together: the sub-environments that
share a plant (same mean wind speed, parameters and ``dt``; the wind direction is a
per-sub-environment factor, see :mod:`dss14_env.envs.plant`) are stepped by ONE matrix product::

    [X+, Y+] = [X, R, T_mean, kappa_az Xi, kappa_el Xi] @ M^T

Everything else (command limiter, encoders, observation, reward, episode end) is elementwise
numpy over the batch.

Seeding rule (the one of ``gymnasium.vector.SyncVectorEnv``): sub-environment ``i`` owns its
own ``numpy.random.Generator``, seeded with ``seed + i`` by ``reset(seed=seed)`` (or ``seed[i]``
for a list; fresh entropy for None on the first reset, continued otherwise).  Every draw of
sub-environment ``i`` -- its episodes (:func:`dss14_env.envs.scenarios.draw_episode`) and its noise
blocks -- comes from that generator in the same order as in a single environment, so the
results equal those of N single environments reset with seeds ``seed + i`` and stepped with
the same actions (up to floating-point rounding, about 1e-10 relative: the single environment
steps the exact 64-state restriction of the same plant).

Autoreset: ``AutoresetMode.NEXT_STEP``, as gymnasium's classic-control vector environments:
the step after a sub-environment terminated or truncated resets it (with the configuration's
defaults; ``reset(options=...)`` applies to the episodes that reset starts) and returns its
first observation with reward 0 and both flags False.  Truncation after ``max_episode_steps``
steps (from the registration, via ``make_vec``).

``info`` holds arrays of shape ``(N,)`` (``action_unclipped``: ``(N, 2)``) with the keys of the
single environment's step info (values of a sub-environment that was just reset describe its
first state); there are no ``_key`` masks.  Rendering is not supported.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dss14_env.envs.env import OBS_ERROR_BOUND, OBS_ERROR_RATE_BOUND, OBS_HIGH, R2D, R2MD
from dss14_env.envs.plant import Plant, get_plant
from dss14_env.envs.scenarios import (
    DEG,
    MDEG,
    NOISE_BLOCK,
    EnvConfig,
    block_rows,
    command,
    draw_episode,
    draw_noise_block,
    load_env_config,
)

_TRAJ_KEYS = ("v", "amp", "omega", "phase", "sin_phase", "step", "t_step", "slew_acc", "slew_t0",
              "slew_ta", "slew_T")


class DSS14VectorEnv(VectorEnv):
    """N DSS-14 servo environments stepped together with numpy (see the module docstring).

    :param num_envs: number of sub-environments N (>= 1)
    :param max_episode_steps: truncate episodes after this many steps (None: never)
    :param render_mode: must be None
    :param config: as for :class:`dss14_env.envs.env.DSS14Env`
    :param overrides: configuration keys
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 render_mode: str | None = None, config: str | EnvConfig | dict | None = None,
                 **overrides: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or a positive integer, got {max_episode_steps!r}")
        if render_mode is not None:
            raise ValueError(f"DSS14VectorEnv does not render (render_mode must be None, got {render_mode!r}); "
                             "use the single environment for rendering")
        self.config = load_env_config(config, **overrides)
        self.num_envs = int(num_envs)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = None
        self.single_action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = spaces.Box(-OBS_HIGH, OBS_HIGH, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        c = self.config
        self._dt = c.dt
        self._scale = c.action_scale_deg_s * DEG
        self._rl = c.rate_limit_deg_s * DEG
        self._dr = c.accel_limit_deg_s2 * DEG * c.dt
        self._inv_es = 1.0 / c.error_scale_mdeg
        self._q = (2.0 * math.pi / 2 ** c.encoder_bits) if c.encoder_bits else 0.0
        self._sig = c.encoder_noise_mdeg * MDEG
        self._el_lo, self._el_hi = (v * DEG for v in c.el_limits_deg)
        self._az_c, self._az_h = c.az_wrap_centre_deg * DEG, c.az_wrap_half_range_deg * DEG
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._Zs = None

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-environment.

        :param seed: int (sub-environment i gets ``seed + i``), a list of N seeds/None, or None
        :param options: episode keys for the episodes this reset starts (all sub-environments)
        :return: observations ``(N, 12)`` and info
        """
        N = self.num_envs
        cfg = self.config.with_options(options)
        if seed is None:
            seeds: list = [None] * N
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(N)]
            super().reset(seed=int(seed))
        else:
            seeds = list(seed)
            if len(seeds) != N:
                raise ValueError(f"seed list must have num_envs = {N} entries, got {len(seeds)}")
        for i, s in enumerate(seeds):
            if s is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(s)[0]
        self._allocate()
        idx = np.arange(N)
        self._reset_envs(idx, cfg)
        return self._reset_obs(idx), self._reset_info()

    def _allocate(self) -> None:
        """Per-sub-environment arrays (sized from the nominal plant)."""
        N = self.num_envs
        p = get_plant(0.0, self.config.dt)  # sizes only
        self._n, self._k_rank = p.n, p.noise_rank
        n, k, m = p.n, p.noise_rank, 4  # outputs: encoders and pointing (Plant.OUTPUTS[:4])
        # plant state, inputs and outputs in *slot* order (sub-environments sorted by plant,
        # slot s holds sub-environment perm[s]); everything else in sub-environment order
        self._Zs = np.zeros((N, n + 4 + 2 * k))
        self._Os = np.zeros((N, n + m))
        self._Y = np.zeros((N, m))
        self._kappa = np.zeros((N, 2))
        self._kappa_s = np.zeros((N, 2))
        self._start = np.zeros((N, 2))
        self._traj = {key: np.zeros((N, 2)) for key in _TRAJ_KEYS}
        self._k = np.zeros(N, np.int64)
        self._j = np.zeros(N, np.int64)
        self._blocks = np.zeros((NOISE_BLOCK, N, 6 + k + 2))  # block_rows, time-major
        self._rp = np.zeros((N, 2))
        self._ap = np.zeros((N, 2))
        self._em = np.zeros((N, 2))
        self._ne0 = np.zeros((N, 2))
        self._hits = np.zeros((N, 2), np.int64)
        self._max_e = np.zeros(N)
        self._wind = np.zeros((N, 2))  # speed (m/s), direction (rad)
        self._pid = np.zeros(N, np.int64)
        self._plants: list = []
        self._prev_done = np.zeros(N, bool)
        self._info_state = self.config.info_state
        self._arange = np.arange(N)
        self._j_uniform = True
        self._obs_high64 = OBS_HIGH.astype(np.float64)
        self._obs_low64 = -self._obs_high64
        self._w = self.config.action_change_weight
        self._rb = (1.0 / self.config.error_scale_mdeg) * (1.0 / self._dt)
        self._clamp_always = False
        self._perm = self._inv = None

    def _matrix(self, plant: Plant) -> np.ndarray:
        """The plant's batch step map without the gust-torque outputs (not observed)."""
        return np.ascontiguousarray(plant.batch_step_matrix[:, :self._n + 4])

    def _plant_id(self, plant: Plant) -> int:
        for i, p in enumerate(self._plants):
            if p is plant:
                return i
        self._plants.append(plant)
        return len(self._plants) - 1

    def _reset_envs(self, idx: np.ndarray, cfg: EnvConfig) -> None:
        """Draw new episodes for the sub-environments ``idx`` (same draws as DSS14Env.reset)."""
        n = self._n
        inv_old = self._inv
        for i in idx.tolist():
            rng = self._rngs[i]
            ep = draw_episode(cfg, rng)
            ne = rng.standard_normal(2) * self._sig if self._sig else np.zeros(2)
            block_rows(ep.traj, 0, self._dt, self._rl, draw_noise_block(rng, self._k_rank, self._sig > 0.0),
                       self._sig, out=self._blocks[:, i])
            p = ep.plant
            self._pid[i] = self._plant_id(p)
            slot = i if inv_old is None else inv_old[i]
            self._Zs[slot, :n] = ep.x0
            self._Zs[slot, n + 2:n + 4] = ep.t_mean
            self._Y[i] = p.C[:4] @ ep.x0
            self._rp[i] = np.clip(ep.r0, -self._rl, self._rl)
            self._ap[i] = self._rp[i] / self._scale
            self._kappa[i] = ep.kappa
            self._start[i] = ep.start
            for key in _TRAJ_KEYS:
                self._traj[key][i] = ep.traj[key]
            self._max_e[i] = cfg.max_error_deg * DEG * R2MD
            self._wind[i] = ep.wind_speed, ep.wind_direction
            self._ne0[i] = ne
        self._k[idx] = 0
        self._j[idx] = 0
        self._hits[idx] = 0
        # drop plants no sub-environment uses, then group the sub-environments by plant
        used = np.unique(self._pid)
        if used.size < len(self._plants):
            remap = np.full(len(self._plants), -1)
            remap[used] = np.arange(used.size)
            self._plants = [self._plants[u] for u in used.tolist()]
            self._pid = remap[self._pid]
        if len(self._plants) == 1:
            perm = None
            self._groups = [(self._matrix(self._plants[0]), 0, self.num_envs)]
        else:  # slots sorted by plant: group g is slots bounds[g]:bounds[g+1]
            perm = np.argsort(self._pid, kind="stable")
            bounds = np.searchsorted(self._pid[perm], np.arange(len(self._plants) + 1))
            self._groups = [(self._matrix(p), int(bounds[g]), int(bounds[g + 1]))
                            for g, p in enumerate(self._plants)]
        old_perm = self._perm
        if not (perm is None and old_perm is None) and (
                perm is None or old_perm is None or not np.array_equal(perm, old_perm)):
            # move the slot-ordered rows: new slot s takes sub-environment perm[s]
            new_perm = self._arange if perm is None else perm
            src = new_perm if inv_old is None else inv_old[new_perm]
            self._Zs = self._Zs[src]
            self._Os = self._Os[src]
            self._perm = perm
            self._inv = None if perm is None else np.argsort(perm, kind="stable")
        self._kappa_s = self._kappa if self._perm is None else self._kappa[self._perm]
        self._any_noise = bool(np.any(self._kappa))
        self._j_uniform = bool(np.all(self._j == self._j[0]))
        # without encoder noise the observation bounds can only be passed on a terminating step
        me, q_mdeg = cfg.max_error_deg * DEG * R2MD, self._q * R2MD
        self._clamp_always = self._clamp_always or bool(self._sig) or \
            (me + q_mdeg) * self._inv_es > OBS_ERROR_BOUND or 2.0 * (me + q_mdeg) * self._rb > OBS_ERROR_RATE_BOUND

    def _reset_obs(self, idx: np.ndarray) -> np.ndarray:
        """Observation rows ``idx`` of freshly reset sub-environments (as DSS14Env.reset)."""
        n = self._n
        tr = {key: v[idx] for key, v in self._traj.items()}
        c, cd = command(tr, np.zeros(idx.size))
        theta = self._Y[idx, 0:2]
        start = self._start[idx]
        a = start + theta + self._ne0[idx] if self._sig else start + theta
        if self._q:
            a = self._q * np.floor(a * (1.0 / self._q) + 0.5)
        rel = a - start
        em = (c - rel) * R2MD
        self._em[idx] = em
        obs = np.empty((idx.size, 12))
        obs[:, 0:2] = np.clip(em * self._inv_es, -OBS_ERROR_BOUND, OBS_ERROR_BOUND)
        obs[:, 2:4] = 0.0
        obs[:, 4:6] = c * R2D
        obs[:, 6:8] = cd * (1.0 / self._rl)
        obs[:, 8:10] = rel * R2D
        obs[:, 10:12] = self._rp[idx] * (1.0 / self._rl)
        return obs.astype(np.float32)

    def _reset_info(self) -> dict[str, Any]:
        n = self._n
        c, _ = command(self._traj, np.zeros(self.num_envs))
        y = self._Y
        e = (c - y[:, 0:2]) * R2MD
        return {"servo_error_az_mdeg": e[:, 0], "servo_error_el_mdeg": e[:, 1],
                "measured_error_az_mdeg": self._em[:, 0].copy(), "measured_error_el_mdeg": self._em[:, 1].copy(),
                "pointing_error_el_mdeg": y[:, 2] * R2MD, "pointing_error_xel_mdeg": y[:, 3] * R2MD,
                "wind_speed_mps": self._wind[:, 0].copy(), "wind_direction_rad": self._wind[:, 1].copy(),
                "rate_command_az_deg_s": self._rp[:, 0] * R2D, "rate_command_el_deg_s": self._rp[:, 1] * R2D,
                "start_az_deg": self._start[:, 0] * R2D, "start_el_deg": self._start[:, 1] * R2D}

    @property
    def n_rate_limited(self) -> np.ndarray:
        """Steps of the current episodes in which the rate clip acted, per sub-environment."""
        return self._hits[:, 0].copy()

    @property
    def n_accel_limited(self) -> np.ndarray:
        """Steps of the current episodes in which the acceleration limit acted."""
        return self._hits[:, 1].copy()

    def plant_states(self) -> np.ndarray:
        """Plant states ``(N, n)`` (balanced coordinates of each sub-environment's plant)."""
        x = self._Zs[:, :self._n]
        return x.copy() if self._perm is None else x[self._inv]

    # ------------------------------------------------------------------ step
    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Step every sub-environment (autoreset the ones that ended on the previous step).

        :param actions: ``(N, 2)``, finite
        :raises ValueError: on a NaN/inf action or a wrong shape
        """
        if self._Zs is None:
            raise RuntimeError("call reset() before step()")
        N, n, k = self.num_envs, self._n, self._k_rank
        try:
            A = np.array(actions, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"actions must be a numeric array of shape ({N}, 2)") from exc
        if A.shape != (N, 2):
            raise ValueError(f"actions must have shape ({N}, 2), got shape {A.shape}")
        if not np.isfinite(A.sum()) and not np.isfinite(A).all():
            raise ValueError(f"actions must be finite; non-finite in sub-environment(s) "
                             f"{np.flatnonzero(~np.isfinite(A).all(axis=1)).tolist()}")
        done = self._prev_done
        any_done = bool(done.any())
        # ---- command limiter
        C = np.clip(A, -1.0, 1.0)
        Q = C * self._scale
        rate_hit = np.abs(Q) > self._rl
        np.clip(Q, -self._rl, self._rl, out=Q)
        rp = self._rp
        Qa = np.clip(Q, rp - self._dr, rp + self._dr)
        acc_hit = Qa != Q
        Q = Qa
        # ---- this step's rows: command at t[k+1] and noise (block_rows; a sub-environment that
        # is about to be reset draws nothing)
        j = self._j
        enc = self._sig > 0.0
        if self._j_uniform:
            j0 = int(j[0])
            if j0 >= NOISE_BLOCK:
                normals = np.zeros((NOISE_BLOCK, N, k + (2 if enc else 0)))
                for i in range(N):
                    if not done[i]:
                        normals[:, i] = draw_noise_block(self._rngs[i], k, enc)
                tr = {key: v[None] for key, v in self._traj.items()}
                block_rows(tr, int(self._k[0]), self._dt, self._rl, normals, self._sig, out=self._blocks)
                j0 = 0
                j[:] = 0
            row = self._blocks[j0]
            j += 1
        else:
            full = j >= NOISE_BLOCK
            if full.any():
                for i in np.flatnonzero(full & ~done).tolist():
                    tr = {key: v[i] for key, v in self._traj.items()}
                    block_rows(tr, int(self._k[i]), self._dt, self._rl, draw_noise_block(self._rngs[i], k, enc),
                               self._sig, out=self._blocks[:, i])
                    j[i] = 0
                np.minimum(j, NOISE_BLOCK - 1, out=j)
            row = self._blocks[j, self._arange]
            j += 1
        Xi = row[:, 6:6 + k]
        # ---- plant: one matrix product per plant
        Zs, Os, perm = self._Zs, self._Os, self._perm
        if perm is None:
            Zs[:, n:n + 2] = Q
        else:
            np.take(Q, perm, axis=0, out=Zs[:, n:n + 2])
        if self._any_noise:
            Xk = Xi if perm is None else np.take(Xi, perm, axis=0)
            np.multiply(Xk, self._kappa_s[:, :1], out=Zs[:, n + 4:n + 4 + k])
            np.multiply(Xk, self._kappa_s[:, 1:], out=Zs[:, n + 4 + k:])
        if perm is None:
            np.matmul(Zs, self._groups[0][0], out=Os)
            Y = Os[:, n:].copy()
        else:
            for MT, a, b in self._groups:
                np.matmul(Zs[a:b], MT, out=Os[a:b])
            Y = np.take(Os[:, n:], self._inv, axis=0)
        Zs[:, :n] = Os[:, :n]
        self._Y = Y
        # ---- command and measurement at t[k+1]
        kk = self._k
        kk += 1
        c = row[:, 0:2]
        theta = Y[:, :2]
        start = self._start
        if self._sig:
            a = start + theta
            a += row[:, 6 + k:]
        else:
            a = start + theta
        if self._q:
            a *= 1.0 / self._q
            a += 0.5
            np.floor(a, out=a)
            a *= self._q
        rel = a
        rel -= start
        em = c - rel
        em *= R2MD
        e = c - theta
        e *= R2MD
        # ---- episode end and reward
        e0, e1 = e[:, 0], e[:, 1]
        ib = self._inv_es
        ab = theta + start
        me = self._max_e
        terminated = ((np.abs(e0) > me) | (np.abs(e1) > me) | (ab[:, 1] < self._el_lo) | (ab[:, 1] > self._el_hi)
                      | (np.abs(ab[:, 0] - self._az_c) > self._az_h))
        any_term = bool(terminated.any())
        d = C - self._ap
        d0, d1 = d[:, 0], d[:, 1]
        cost = (e0 * e0 + e1 * e1) * (ib * ib) + self._w * (d0 * d0 + d1 * d1)
        if any_term:
            cost += terminated * self.config.termination_penalty
        reward = np.negative(cost, out=cost)
        # ---- observation (float32 written directly; bounds only reachable when terminating)
        obs = np.empty((N, 12), np.float32)
        np.multiply(em, ib, out=obs[:, 0:2], casting="same_kind")
        np.multiply(em - self._em, self._rb, out=obs[:, 2:4], casting="same_kind")
        obs[:, 4:8] = row[:, 2:6]
        np.multiply(rel, R2D, out=obs[:, 8:10], casting="same_kind")
        np.multiply(Q, 1.0 / self._rl, out=obs[:, 10:12], casting="same_kind")
        if any_term or self._clamp_always:
            o = np.empty((N, 4))
            np.multiply(em, ib, out=o[:, 0:2])
            np.multiply(em - self._em, self._rb, out=o[:, 2:4])
            np.clip(o, self._obs_low64[:4], self._obs_high64[:4], out=o)
            obs[:, 0:4] = o
        truncated = (kk >= self.max_episode_steps) if self.max_episode_steps is not None else np.zeros(N, bool)
        self._em = em
        self._ap = C
        self._rp = Q
        rate_any = rate_hit[:, 0] | rate_hit[:, 1]
        acc_any = acc_hit[:, 0] | acc_hit[:, 1]
        self._hits[:, 0] += rate_any
        self._hits[:, 1] += acc_any
        info = {"servo_error_az_mdeg": e0, "servo_error_el_mdeg": e1,
                "measured_error_az_mdeg": em[:, 0].copy(), "measured_error_el_mdeg": em[:, 1].copy(),
                "pointing_error_el_mdeg": Y[:, 2] * R2MD, "pointing_error_xel_mdeg": Y[:, 3] * R2MD,
                "wind_speed_mps": self._wind[:, 0].copy(), "wind_direction_rad": self._wind[:, 1].copy(),
                "action_unclipped": A,
                "rate_command_az_deg_s": Q[:, 0] * R2D, "rate_command_el_deg_s": Q[:, 1] * R2D,
                "rate_limited": rate_any, "accel_limited": acc_any,
                "n_rate_limited": self._hits[:, 0].copy(), "n_accel_limited": self._hits[:, 1].copy()}
        if self._info_state:
            info["plant_state"] = self.plant_states()
        # ---- autoreset (NEXT_STEP): sub-environments that ended on the previous step
        if any_done:
            idx = np.flatnonzero(done)
            self._reset_envs(idx, self.config)
            obs[idx] = self._reset_obs(idx)
            reward[idx] = 0.0
            terminated[idx] = False
            truncated[idx] = False
            Yr = self._Y[idx]
            tr = {key: v[idx] for key, v in self._traj.items()}
            cr, _ = command(tr, np.zeros(idx.size))
            er = (cr - Yr[:, :2]) * R2MD
            info["servo_error_az_mdeg"][idx], info["servo_error_el_mdeg"][idx] = er[:, 0], er[:, 1]
            info["measured_error_az_mdeg"][idx] = self._em[idx, 0]
            info["measured_error_el_mdeg"][idx] = self._em[idx, 1]
            info["pointing_error_el_mdeg"][idx] = Yr[:, 2] * R2MD
            info["pointing_error_xel_mdeg"][idx] = Yr[:, 3] * R2MD
            info["wind_speed_mps"][idx], info["wind_direction_rad"][idx] = self._wind[idx, 0], self._wind[idx, 1]
            info["rate_command_az_deg_s"][idx] = self._rp[idx, 0] * R2D
            info["rate_command_el_deg_s"][idx] = self._rp[idx, 1] * R2D
            info["rate_limited"][idx] = info["accel_limited"][idx] = False
            info["n_rate_limited"][idx] = info["n_accel_limited"][idx] = 0
            if self._info_state:
                info["plant_state"] = self.plant_states()
            self._prev_done = terminated | truncated
        elif terminated.any() or truncated.any():
            self._prev_done = terminated | truncated
        return obs, reward, terminated, truncated, info

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release."""
