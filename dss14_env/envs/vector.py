"""numpy-batched vector version of :class:`dss14_env.envs.env.DSS14Env`.

``gymnasium.make_vec("DSS14-v0", num_envs=N, vectorization_mode="vector_entry_point")`` builds
:class:`DSS14VectorEnv`.  All N sub-environments advance together: the sub-environments that
share a plant (same mean wind speed, parameters and ``dt``; the wind direction is a
per-sub-environment factor, see :mod:`dss14_env.envs.plant`) are stepped by ONE matrix product::

    [X+, Y+] = [X, R, T_mean, kappa_az Xi, kappa_el Xi] @ M^T

Everything else -- command limiter, encoders, errors, episode end, reward, observation, info
-- is the step of :mod:`dss14_env.envs.fused`, the compiled loops over the sub-environments
that the single environment runs with N = 1 (the first reset and step compile them, some
seconds per process).

Seeding rule (the one of ``gymnasium.vector.SyncVectorEnv``): sub-environment ``i`` owns its
own ``numpy.random.Generator``, seeded with ``seed + i`` by ``reset(seed=seed)`` (or ``seed[i]``
for a sequence; fresh entropy for None on the first reset, continued otherwise).  Every draw of
sub-environment ``i`` -- its episodes (:func:`dss14_env.envs.scenarios.draw_episode`) and its
noise blocks -- comes from that generator in the same order as in a single environment, so the
results equal those of N single environments reset with seeds ``seed + i`` and stepped with
the same actions (up to floating-point rounding, 1e-11 to 1e-9 relative depending on the BLAS
kernel: the single environment steps the exact 64-state restriction of the same plant).

Autoreset: ``AutoresetMode.NEXT_STEP``, as gymnasium's classic-control vector environments:
the step after a sub-environment terminated or truncated resets it (with the configuration's
defaults; ``reset(options=...)`` applies to the episodes that reset starts) and returns its
first observation with reward 0 and both flags False.  Truncation after ``max_episode_steps``
steps (from the registration, via ``make_vec``).

``info`` holds arrays of shape ``(N,)`` (``action_unclipped``: ``(N, 2)``) with the keys of the
single environment's step info (values of a sub-environment that was just reset describe its
first state); there are no ``_key`` masks.  The reset info has the keys of the single
environment's reset info, one entry per sub-environment (``scenario``, ``params``,
``params_rejected`` and ``wind_loads`` as object arrays).  Rendering is not supported.  ``copy.deepcopy``, a
pickle round trip and :meth:`DSS14VectorEnv.get_state` / ``set_state`` continue bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dss14_env.core.units import DEG, R2MD
from dss14_env.envs import fused
from dss14_env.envs.config import EnvConfig, load_env_config
from dss14_env.envs.core import StepConstants, StepState, as_actions, check_seeds
from dss14_env.envs.env import EnvState, check_snapshot, restore, snapshot
from dss14_env.envs.monopulse import (
    MonopulseConstants,
    MonopulseState,
    observation_high,
    sensor_constants,
    sensor_observe,
    sensor_reset,
    sensor_step,
)
from dss14_env.envs.plant import N_STEP_OUTPUTS, Plant, PlantFactory, resolve_factory
from dss14_env.envs.scenarios import (
    NOISE_BLOCK,
    Episode,
    command,
    command_parts,
    draw_noise_block,
    draw_reset,
    episode_info,
    noise_width,
)

#: the most slots of one plant product: the blocks of the product ``(N, n + 4 + 2 k) @ (n + 4 + 2 k,
#: n + 4)`` stay in the cache (and under OpenBLAS's small-matrix size): 187 us against 240 us for
#: one product of all 1 024 rows of the 68-state plant (one BLAS thread, a 2-core machine)
PRODUCT_ROWS = 128
_TRAJ_KEYS = ("v", "amp", "omega", "phase", "sin_phase", "step", "t_step", "slew_acc", "slew_t0",
              "slew_ta", "slew_T")


def _stacked(rows: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """One array of shape ``(N,)`` per key of the per-sub-environment dicts ``rows``: floats
    as a float array, anything else (names, dicts) as an object array.
    """
    out = {}
    for key in rows[0]:
        values = [row[key] for row in rows]
        if all(isinstance(v, float) for v in values):
            out[key] = np.array(values)
        else:
            out[key] = np.empty(len(values), object)
            out[key][:] = values
    return out


class DSS14VectorEnv(VectorEnv):
    """N DSS-14 servo environments stepped together with numpy (see the module docstring).

    :param num_envs: number of sub-environments N (>= 1)
    :param max_episode_steps: truncate episodes after this many steps (None: never)
    :param render_mode: must be None
    :param config: as for :class:`dss14_env.envs.env.DSS14Env`
    :param model_config: as for :class:`dss14_env.envs.env.DSS14Env` (one model for all)
    :param recalibrate_wind: as for :class:`dss14_env.envs.env.DSS14Env` (the wind-load choice
        is ``self.plants.wind_loads``)
    :param compiled: None or True (the step is always the compiled loops of
        :mod:`dss14_env.envs.fused`; kept for callers that name it); False is refused
    :param overrides: configuration keys
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 render_mode: str | None = None, config: str | EnvConfig | dict | None = None,
                 model_config: Any = None, recalibrate_wind: bool | None = None,
                 compiled: bool | None = None, **overrides: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or a positive integer, got "
                             f"{max_episode_steps!r}")
        if not (compiled is None or compiled is True or compiled is np.True_):
            raise ValueError(f"compiled must be None or True (the step is always compiled), got {compiled!r}")
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (DSS14VectorEnv does not render; use the single "
                             f"environment), got {render_mode!r}")
        self.config = load_env_config(config, **overrides)
        #: the model's plants (:class:`~dss14_env.envs.plant.PlantFactory`), shared by all
        self.plants: PlantFactory = resolve_factory(model_config, recalibrate_wind)
        if self.config.params is not None:
            self.plants.check_params(self.config.params, self.config.source_of("params"))
        self.num_envs = int(num_envs)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = None
        self.single_action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        high = observation_high(self.config.sensors)
        self.single_observation_space = spaces.Box(-high, high, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.constants = StepConstants.from_config(self.config)
        #: the monopulse sensor's constants (None without it)
        self.monopulse = (MonopulseConstants.from_config(self.config) if "monopulse" in self.config.sensors
                          else None)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._Z = None
        #: the step runs compiled (:mod:`dss14_env.envs.fused`): always True
        self.compiled = True
        self._kc = fused.constants(self.constants, self.plants.xel_scale)
        self._mc = sensor_constants(self.monopulse) if self.monopulse is not None else None
        self._width = high.size

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-environment.

        :param seed: None, a non-negative integer (sub-environment i gets ``seed + i``) or a
            sequence of N such seeds / None
        :param options: episode keys for the episodes this reset starts (all sub-environments)
        :return: observations ``(N, 12)`` and info
        :raises ValueError: a bad seed or option, before anything changes
        """
        N = self.num_envs
        seeds = check_seeds(seed, N)
        cfg = self.config.with_options(options)
        if cfg.params is not None:
            self.plants.check_params(cfg.params, cfg.source_of("params"))
        if seed is not None and not isinstance(seed, (list, tuple, np.ndarray)):
            super().reset(seed=seeds[0])
        for i, s in enumerate(seeds):
            if s is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(s)[0]
        self._allocate()
        idx = np.arange(N)
        episodes = self._reset_envs(idx, cfg)
        obs, info = self._reset_rows(idx)
        return obs, {**_stacked([episode_info(ep, self.plants.wind_loads) for ep in episodes]), **info}

    def _allocate(self) -> None:
        """Per-sub-environment arrays (sized from the nominal plant)."""
        N = self.num_envs
        p = self.plants.plant(0.0, self.config.dt)  # sizes only
        self._n, self._k_rank = p.n, p.noise_rank
        n, k = p.n, p.noise_rank
        # plant state, inputs and outputs in *slot* order (sub-environments sorted by plant,
        # slot s holds sub-environment perm[s]), one row per slot: two step buffers
        # [x, r, T_mean, kappa_az xi, kappa_el xi] of which _cur is this step's, the matrix
        # product writing [x+, y+] into the other; everything else in sub-environment order
        self._Z = np.zeros((2, N, n + 4 + 2 * k))
        self._cur = 0
        self._t_mean_s = np.zeros((2, N))
        self._Y = np.zeros((N, N_STEP_OUTPUTS))  # the step outputs at each episode's start
        self._kappa = np.zeros((N, 2))
        self._kappa_s = np.zeros((2, N))
        self._start = np.zeros((N, 2))
        self._traj = {key: np.zeros((N, 2)) for key in _TRAJ_KEYS}
        self._k = np.zeros(N, np.int64)
        #: the sub-environments' noise blocks (:func:`~dss14_env.envs.scenarios.draw_noise_block`),
        #: a time-major ring: every step reads slot ``g mod NOISE_BLOCK`` (``g`` the steps since
        #: the first reset), one contiguous row per sub-environment, whatever its row ``j`` in its
        #: block (a block is written from the slot its row 0 is read at)
        self._noise = np.zeros((NOISE_BLOCK, N, self._noise_width()))
        self._stage = np.empty((N, NOISE_BLOCK, self._noise_width()))  # blocks as drawn
        self._g = 0
        self._jmax = 0  # the largest row j, kept without a pass over j
        self._parts = (False, False, False)
        #: the step state of every sub-environment (:class:`~dss14_env.envs.core.StepState`)
        self._s = StepState(np.zeros((N, 2)), np.zeros((N, 2)), np.zeros((N, 2)), np.zeros((N, 2)),
                            np.zeros(N, np.int64))
        self._r0 = np.zeros((N, 2))  # the drawn start rate commands and t = 0 encoder noise,
        self._ne0 = np.zeros((N, 2))  # until _reset_rows makes the state of them
        self._z0 = np.zeros((N, 2))  # and the monopulse sensor's start normals
        #: the monopulse sensor's state (None without it)
        self._mp: MonopulseState | None = None
        self._max_e = np.zeros(N)
        self._episode = np.zeros((N, 5))  # fused.episode_rows of _start, _max_e and _wind
        self._wind = np.zeros((N, 2))  # speed (m/s), direction (rad)
        self._pid = np.zeros(N, np.int64)
        self._plants: list[Plant] = []
        self._groups: list = []
        self._prev_done = np.zeros(N, bool)
        self._arange = np.arange(N)
        self._any_noise = False
        self._clamp_always = False
        self._perm = self._inv = None

    def _plant_id(self, plant: Plant) -> int:
        for i, p in enumerate(self._plants):
            if p is plant:
                return i
        self._plants.append(plant)
        return len(self._plants) - 1

    def _reset_envs(self, idx: np.ndarray, cfg: EnvConfig) -> list[Episode]:
        """Draw new episodes for the sub-environments ``idx`` (same draws as DSS14Env.reset);
        returns them in the order of ``idx``.
        """
        k = self.constants
        inv_old = self._inv
        draws = [draw_reset(cfg, self._rngs[i], self.plants, k.encoder_sigma) for i in idx.tolist()]
        episodes = [ep for ep, _, _, _ in draws]
        self._store_episodes(idx, episodes, inv_old)
        self._put_blocks(idx, np.stack([normals for _, _, _, normals in draws], axis=1))
        self._ne0[idx] = [ne for _, ne, _, _ in draws]
        self._z0[idx] = [z0 for _, _, z0, _ in draws]
        self._max_e[idx] = cfg.max_error_deg * DEG * R2MD
        self._episode = fused.episode_rows(self._start, self._max_e, self._wind)
        self._k[idx] = 0
        self._s.j[idx] = 0
        self._jmax = int(self._s.j.max())
        self._parts = command_parts(self._traj)
        self._regroup(inv_old)
        self._clamp_always = any(k.clamp_always(me) for me in np.unique(self._max_e).tolist())
        return episodes

    def _store_episodes(self, idx: np.ndarray, episodes: list[Episode], inv_old: np.ndarray | None) -> None:
        """Write the drawn episodes of the sub-environments ``idx`` into the per-sub-environment
        arrays (the plant state into the slots of the slot order ``inv_old``), one assignment
        per array.
        """
        n = self._n
        self._pid[idx] = [self._plant_id(ep.plant) for ep in episodes]
        slots = idx if inv_old is None else inv_old[idx]
        Z = self._Z[self._cur]
        Z[slots, :n] = [ep.x0 for ep in episodes]
        self._t_mean_s[:, slots] = np.stack([ep.t_mean for ep in episodes], axis=1)
        self._Y[idx] = [ep.plant.C[:N_STEP_OUTPUTS] @ ep.x0 for ep in episodes]
        self._r0[idx] = [ep.r0 for ep in episodes]
        self._kappa[idx] = [ep.kappa for ep in episodes]
        self._start[idx] = [ep.start for ep in episodes]
        for key in _TRAJ_KEYS:
            self._traj[key][idx] = [ep.traj[key] for ep in episodes]
        self._wind[idx] = [(ep.wind_speed, ep.wind_direction) for ep in episodes]

    def _regroup(self, inv_old: np.ndarray | None) -> None:
        """Drop plants no sub-environment uses, then group the sub-environments by plant."""
        used = np.unique(self._pid)
        if used.size < len(self._plants):
            remap = np.full(len(self._plants), -1)
            remap[used] = np.arange(used.size)
            self._plants = [self._plants[u] for u in used.tolist()]
            self._pid = remap[self._pid]
        if len(self._plants) == 1:
            perm, bounds = None, [0, self.num_envs]
        else:  # slots sorted by plant: group g is slots bounds[g]:bounds[g+1]
            perm = np.argsort(self._pid, kind="stable")
            bounds = np.searchsorted(self._pid[perm], np.arange(len(self._plants) + 1)).tolist()
        self._groups = [(p.vector_step_matrix, a, min(a + PRODUCT_ROWS, bounds[g + 1]))
                        for g, p in enumerate(self._plants)
                        for a in range(bounds[g], bounds[g + 1], PRODUCT_ROWS)]
        old_perm = self._perm
        if not (perm is None and old_perm is None) and (
                perm is None or old_perm is None or not np.array_equal(perm, old_perm)):
            # move the slot-ordered rows: new slot s takes sub-environment perm[s]
            new_perm = self._arange if perm is None else perm
            src = new_perm if inv_old is None else inv_old[new_perm]
            self._Z[self._cur] = self._Z[self._cur][src]
            self._t_mean_s = np.ascontiguousarray(self._t_mean_s[:, src])
            self._perm = perm
            self._inv = None if perm is None else np.argsort(perm, kind="stable")
        kappa = self._kappa if self._perm is None else self._kappa[self._perm]
        self._kappa_s = np.ascontiguousarray(kappa.T)  # rows az, el: one per product input
        self._any_noise = bool(np.any(self._kappa))

    def _reset_rows(self, idx: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        """Observation rows and info of freshly reset sub-environments ``idx`` (as DSS14Env.reset)."""
        tr = {key: v[idx] for key, v in self._traj.items()}
        c, cd = command(tr, np.zeros(idx.size))
        st, obs, info = fused.reset_state(c, cd, self._Y[idx], self._ne0[idx], self._r0[idx],
                                          self._episode[idx], self._kc, self.constants, self._width)
        for name in ("r_prev", "a_prev", "em_prev", "hits"):
            getattr(self._s, name)[idx] = getattr(st, name)
        if self.monopulse is not None:
            p0 = np.column_stack((info["pointing_error_el_mdeg"], info["pointing_error_xel_mdeg"]))
            rows = sensor_reset(p0, self._z0[idx], self.monopulse)
            if self._mp is None or idx.size == self.num_envs:
                self._mp = rows
            else:
                for mine, new in zip(self._mp, rows, strict=True):
                    mine[idx] = new
            sensor_observe(rows.out, 1.0 / self.constants.error_scale, obs)
            info["monopulse_el_mdeg"], info["monopulse_xel_mdeg"] = rows.out.T.copy()
        return obs, info

    def _reset_obs(self, idx: np.ndarray) -> np.ndarray:
        """Observation rows of freshly reset sub-environments ``idx`` (:meth:`_reset_rows`)."""
        return self._reset_rows(idx)[0]

    def reset_now(self, idx: np.ndarray) -> np.ndarray:
        """Start the next episode of the sub-environments ``idx`` now, with the draws the
        autoreset of the next :meth:`step` would make (each from its own generator, under the
        configuration), so that the next step does not reset them again: gymnasium's
        ``AutoresetMode.SAME_STEP`` on top of this class' NEXT_STEP.

        :param idx: indices of sub-environments whose episode ended on the last step
        :return: their first observations, ``(len(idx), 12)``
        """
        idx = np.asarray(idx, dtype=np.intp)
        self._reset_envs(idx, self.config)
        pending = self._prev_done.copy()  # (a new array: a snapshot may hold the old one)
        pending[idx] = False
        self._prev_done = pending
        return self._reset_obs(idx)

    @property
    def wind_speeds_mps(self) -> np.ndarray:
        """The current episodes' mean wind speeds, m/s ``(N,)``: each row's reset info
        ``wind_speed_mps`` (what an anemometer reads, never the gust state), set at every reset
        and autoreset of the row; a copy.
        """
        return self._wind[:, 0].copy()

    @property
    def n_rate_limited(self) -> np.ndarray:
        """Steps of the current episodes in which the rate clip acted, per sub-environment."""
        return self._s.hits[:, 0].astype(np.int64)

    @property
    def n_accel_limited(self) -> np.ndarray:
        """Steps of the current episodes in which the acceleration limit acted."""
        return self._s.hits[:, 1].astype(np.int64)

    def plant_states(self) -> np.ndarray:
        """Plant states ``(N, n)`` (balanced coordinates of each sub-environment's plant)."""
        x = self._Z[self._cur, :, :self._n]
        return x.copy() if self._perm is None else x[self._inv]

    # ------------------------------------------------------------------ step
    def _normals(self, done: np.ndarray) -> np.ndarray:
        """This step's standard normals ``(N, k [+ 2])`` (a row of each sub-environment's noise
        block), drawing the next noise blocks where due (not for the sub-environments about to
        be reset: their rows are not used).
        """
        j = self._s.j
        if self._jmax >= NOISE_BLOCK:
            due = np.flatnonzero((j >= NOISE_BLOCK) & ~done)
            self._draw_blocks(due)
            j[due] = 0
            self._jmax = int(j.max())
        rows = self._noise[self._g % NOISE_BLOCK]
        j += 1
        self._jmax += 1
        self._g += 1
        return rows

    def _noise_width(self) -> int:
        """Standard normals per step: the noise rank, plus 2 with encoder noise, plus 2 with the
        monopulse sensor (:func:`dss14_env.envs.scenarios.noise_width`).
        """
        return noise_width(self._k_rank, self.constants.encoder_sigma > 0.0, self.monopulse is not None)

    def _draw_blocks(self, idx: np.ndarray) -> None:
        """The next noise blocks of the sub-environments ``idx``, each from its own generator
        (drawn block by block, then stored in the ring, :meth:`_put_blocks`).
        """
        blocks = self._stage[:idx.size]
        enc = self.constants.encoder_sigma > 0.0
        for b, i in zip(blocks, idx.tolist(), strict=True):
            draw_noise_block(self._rngs[i], self._k_rank, enc, out=b, monopulse=self.monopulse is not None)
        self._put_blocks(idx, blocks.transpose(1, 0, 2))

    def _put_blocks(self, idx: np.ndarray, blocks: np.ndarray) -> None:
        """Store the noise blocks ``(NOISE_BLOCK, len(idx), width)`` of the sub-environments
        ``idx`` (sorted) in the ring, row 0 at the slot the next step reads.
        """
        s0 = self._g % NOISE_BLOCK
        tail = NOISE_BLOCK - s0
        if idx.size == self.num_envs:  # all of them: plain copies, not scatters
            self._noise[s0:] = blocks[:tail]
            self._noise[:s0] = blocks[tail:]
        else:
            self._noise[s0:, idx] = blocks[:tail]
            self._noise[:s0, idx] = blocks[tail:]

    def _commands(self) -> tuple[np.ndarray, np.ndarray]:
        """The commands at the end of this step, ``t = (k + 1) dt``, of every sub-environment
        (:func:`dss14_env.envs.scenarios.command`): rad and rad/s, ``(N, 2)`` each.
        """
        return command(self._traj, (self._k + 1) * self.constants.dt, self._parts)

    def _product(self) -> np.ndarray:
        """The plant products from this step's buffer into the other (which becomes this
        step's), in blocks of at most :data:`PRODUCT_ROWS` slots of one plant: the buffer
        ``(N, n + 4 + 2 k)`` in slot order, the step outputs in its columns ``n .. n + 3``.
        """
        m = self._n + N_STEP_OUTPUTS
        Z, nxt = self._Z[self._cur], self._Z[1 - self._cur]
        for M, a, b in self._groups:
            np.matmul(Z[a:b], M, out=nxt[a:b, :m])
        self._cur = 1 - self._cur
        return nxt

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Step every sub-environment (autoreset the ones that ended on the previous step).

        :param actions: ``(N, 2)`` finite real numbers
        :raises ValueError: a bad action (:func:`dss14_env.envs.core.as_actions`), before
            anything changes
        :raises FloatingPointError: a reward became NaN or infinite (the plant left the range
            it is meant for)
        """
        if self._Z is None:
            raise RuntimeError("call reset() before step()")
        A = as_actions(actions, (self.num_envs, 2))
        N, n, k, s = self.num_envs, self._n, self._k_rank, self._s
        a, R, hit = np.empty((N, 2)), np.empty((N, 2)), np.empty((2, N))
        normals = self._normals(self._prev_done)
        perm = self._arange if self._perm is None else self._perm
        fused.before_product(A, s.r_prev, self._kc, perm, self._kappa_s, self._t_mean_s, normals,
                             self._any_noise, n, k, self._Z[self._cur], a, R, hit)
        c, cd = self._commands()
        y = self._product()
        self._k += 1
        sigma = self.constants.encoder_sigma
        noise = (normals[:, k:k + 2] * sigma)[None] if sigma else fused.NO_NOISE
        obs, em, out = fused.step_outputs(N, self._width)
        inv = self._arange if self._inv is None else self._inv
        flags = fused.after_product(y, n, inv, c[None], cd[None], noise, 0, self._episode, a, s.a_prev,
                                    s.em_prev, R, hit, s.hits, self._kc, self._clamp_always, obs, em, out)
        rew, term = out[fused.REWARD_ROW], out[fused.TERMINATED_ROW] != 0.0
        if flags & fused.NON_FINITE:
            bad = np.flatnonzero(~np.isfinite(rew)).tolist()
            raise FloatingPointError(f"the reward became non-finite in sub-environment(s) {bad}: the plant "
                                     "left the range it is meant for")
        trunc = self._truncated()
        self._s = StepState(R, a, em, s.hits, s.j)
        info = fused.info_arrays(out, A, hit)
        if self.monopulse is not None:
            mp = self._mp
            sensor_step(mp.history, mp.out, mp.k, out[fused.POINTING_ROWS[0]:fused.POINTING_ROWS[1] + 1],
                        normals[None], 0, self._mc, 1.0 / self.constants.error_scale, obs)
            info["monopulse_el_mdeg"], info["monopulse_xel_mdeg"] = mp.out[:, 0].copy(), mp.out[:, 1].copy()
        return self._autoreset(obs, rew, term, trunc, info, bool(flags & fused.ANY_TERMINATED))

    def _truncated(self) -> np.ndarray:
        """Which sub-environments reach ``max_episode_steps`` with this step."""
        if self.max_episode_steps is None:
            return np.zeros(self.num_envs, bool)
        return self._k >= self.max_episode_steps

    def _autoreset(self, obs: np.ndarray, rew: np.ndarray, term: np.ndarray, trunc: np.ndarray, info: dict,
                   any_term: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Reset the sub-environments that ended on the previous step (``AutoresetMode.NEXT_STEP``)
        into this step's results; keep which end on this one (``any_term``: whether one
        terminated).
        """
        done = self._prev_done
        if done.any():
            idx = np.flatnonzero(done)
            self._reset_envs(idx, self.config)
            obs[idx], reset_info = self._reset_rows(idx)
            rew[idx] = 0.0
            term[idx] = False
            trunc[idx] = False
            for key, v in reset_info.items():
                info[key][idx] = v
            info["rate_limited"][idx] = info["accel_limited"][idx] = False
            info["n_rate_limited"][idx] = info["n_accel_limited"][idx] = 0
            self._prev_done = term | trunc
        elif any_term or trunc.any():
            self._prev_done = term | trunc
        if self.config.info_state:
            info["plant_state"] = self.plant_states()
        return obs, rew, term, trunc, info

    # ------------------------------------------------------------------ copies and state
    #: the attributes of the dynamic state (:meth:`get_state`)
    _STATE = ("_Z", "_cur", "_t_mean_s", "_Y", "_kappa", "_kappa_s", "_start", "_traj", "_parts", "_k", "_s",
              "_noise", "_g", "_jmax", "_r0", "_ne0", "_z0", "_mp", "_max_e", "_episode", "_wind", "_pid",
              "_plants", "_groups",
              "_prev_done", "_any_noise", "_clamp_always", "_perm", "_inv", "_rngs", "_np_random",
              "_np_random_seed")

    def get_state(self) -> EnvState:
        """A snapshot of every sub-environment's dynamic state that :meth:`set_state` restores:
        the environment then continues bit for bit as from the snapshot.

        :raises RuntimeError: before the first reset
        """
        if self._Z is None:
            raise RuntimeError("call reset() before get_state()")
        shared = tuple(self._plants) + tuple(g[0] for g in self._groups)
        return snapshot(self, self.__dict__, tuple(n for n in self._STATE if n in self.__dict__), shared)

    def set_state(self, state: EnvState) -> None:
        """Restore a snapshot of :meth:`get_state` (of this environment or a copy of it).

        :raises ValueError: not such a snapshot (another class, number of sub-environments,
            configuration or model; a part missing or of the wrong shape), before anything
            changes
        """
        check_snapshot(self, state, tuple(n for n in self._STATE if not n.startswith("_np_random")))
        self._check_shapes(state.data)
        shared = tuple(state.data["_plants"]) + tuple(g[0] for g in state.data["_groups"])
        self.__dict__.update(restore(self, state, shared))

    def _check_shapes(self, data: dict) -> None:
        """Every per-sub-environment part of the snapshot has ``num_envs`` rows of this model's
        sizes (:meth:`set_state`).
        """
        N, p = self.num_envs, self.plants.plant(0.0, self.config.dt)
        n, k = p.n, p.noise_rank
        s = data["_s"]
        shapes = {"_Z": (2, N, n + 4 + 2 * k), "_t_mean_s": (2, N), "_Y": (N, N_STEP_OUTPUTS),
                  "_noise": (NOISE_BLOCK, N, self._noise_width()), "_start": (N, 2), "_k": (N,),
                  "_wind": (N, 2), "_max_e": (N,), "_episode": (N, 5), "_r0": (N, 2), "_ne0": (N, 2),
                  "_z0": (N, 2),
                  "_prev_done": (N,), "_pid": (N,),
                  "_kappa": (N, 2), "_kappa_s": (2, N)}
        bad = [name for name, shape in shapes.items()
               if not isinstance(data[name], np.ndarray) or data[name].shape != shape]
        if not isinstance(s, StepState) or any(np.shape(v)[:1] != (N,) for v in s):
            bad.append("_s")
        if not isinstance(data["_rngs"], list) or len(data["_rngs"]) != N:
            bad.append("_rngs")
        bad += [name for name in ("_perm", "_inv") if data[name] is not None and np.shape(data[name]) != (N,)]
        if bad:
            raise ValueError(f"state must hold {N} sub-environments of this model ({n} states, {k} noise "
                             f"inputs): its part(s) {', '.join(bad)} have other shapes")

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release."""

