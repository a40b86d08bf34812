"""The plant of the DSS14 environments: the closed rate loop (Eq. 56) in gusty wind, exactly
discretised for a held rate command.

Continuous model (SI).  The rate loop ``x_r' = A_r x_r + B_r r + B_w T_w`` (60 states, inputs
the axis rate commands ``r`` in rad/s and the wind torques ``T_w = [Tw_az, Tw_el]`` in N*m) is
driven by the Davenport gusts of :mod:`dss14_env.wind.loads`: ``T_w = T_mean + g u``, with the
gust speed ``u = C_f x_f`` from the shaping filter ``x_f' = A_f x_f + G_f w`` (``w`` unit white
noise) and the gust gain ``g = [g_az, g_el]`` (N*m per m/s), which depends on the mean speed
``U`` and the direction.  To make one discretised plant serve every direction, the filter is
carried twice, scaled by the direction factors ``kappa = g / g_0(U)``::

    x_a = kappa_az x_f,   x_e = kappa_el x_f,   Tw_gust = g_0 [C_f x_a, C_f x_e]

``g_0(U) = rho U A D c_ref`` is a reference gust gain (``c_ref`` the largest calibrated moment
coefficient), so ``|kappa| <= sqrt(2)``.  The joint state ``x = [x_r, x_a, x_e]`` (60 + 4 + 4 =
68 states) obeys ``x' = A x + B_r r + B_T T_mean + (kappa_az G_a + kappa_el G_e) w`` with ``A``,
``B_r``, ``B_T``, ``G_a``, ``G_e`` independent of the direction.  The realisation is balanced
(:func:`dss14_env.model.linsys.balance`) before anything else is computed from it.

Discretisation (:func:`dss14_env.model.linsys.discretize`, no Euler): over one control period ``dt``
with ``r`` and ``T_mean`` held (zero-order hold)::

    x[k+1] = Ad x[k] + Bd_r r[k] + Bd_T T_mean + L_a (kappa_az xi[k]) + L_e (kappa_el xi[k])

``xi[k] ~ N(0, I_4)``.  ``[L_a; L_e]`` factors the joint covariance of the two noise
increments (Van Loan's integral ``int e^{As} W e^{A^T s} ds`` with ``W = G_i G_j^T``), so that
``L L^T`` with ``L = kappa_az L_a + kappa_el L_e`` is the exact increment covariance for any
direction.  The factor keeps the 4 largest eigen-directions (one per filter state); what it
drops is at round-off level (< 1e-14 of the trace) for dt <= 0.02 s, 1.2e-9 at dt = 0.1 s
(the longest period) on the nominal plant at 90 km/h and up to 1.4e-8 on plants drawn from
the report's ranges (4000 draws, ``randomize_params``; checked against
:data:`NOISE_TAIL_TOL`).  The gust evolves inside the period; only the command and the mean
torque are held.

Within one episode the two filter copies stay proportional, so the single environment steps
the exact 64-state restriction ``[x_r, x_f]`` (:meth:`Plant.one_copy_projection`); the vector
environment steps the 68-state form, whose matrices serve every direction at once.

Outputs ``y = C x``: :data:`OUTPUTS` (encoder angles and the dish's pointing angles in rad --
elevation and cross-elevation, deformation included -- and the gust torques in N*m).

Plants belong to their model: a :class:`PlantFactory` holds one calibrated model and its wind
loads and builds and keeps its plants per (parameters, U, dt).  The wind-load (moment)
coefficients are the dish's aerodynamics, not a property of the drives: a user's model keeps
the shipped ones (calibrated to [R] Table 4 on the shipped model), so a changed drive shows its
effect on the servo errors; refitting them to Table 4 on the user's model is an opt-in
(``recalibrate_wind=True``, or the model file's ``recalibrate_wind: true``).  Factories are
kept per model configuration file (its path and content) and that choice in
:data:`PLANT_FACTORIES`, so the environments built on one file share one calibration.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Mapping
from functools import cached_property, lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import linalg

from dss14_env.core.schema import config_path
from dss14_env.core.threads import single_threaded
from dss14_env.model.assembly import build_model, default_model
from dss14_env.model.config import ModelConfig, load_model_config
from dss14_env.model.linsys import balance, discretize, noise_factor, van_loan
from dss14_env.model.uncertainty import SWEEP_PARAMS, ParamDraw, draw_params, perturbed_rate_loop
from dss14_env.wind.loads import calibrate_wind_loads, default_wind_loads

if TYPE_CHECKING:  # annotations only
    import control as ct

    from dss14_env.model.assembly import DSS14Model
    from dss14_env.wind.loads import WindLoads

#: rows of :attr:`Plant.C`: encoder angles (rad), dish pointing angles (rad), gust torques (N*m)
OUTPUTS = ("enc_az", "enc_el", "point_el", "point_xel", "gust_torque_az", "gust_torque_el")
#: what the encoder rows (``enc_az``, ``enc_el``) of :attr:`Plant.C` measure: the rate loop's
#: outputs and their factors (``"xel"``: divided by ``xel_scale``, the az axis angle of the
#: structure's cross-elevation pointing angle)
ENCODER_OUTPUTS = {"drive": (("enc_az", None), ("enc_el", None)),
                   "axis": (("point_xel", "xel"), ("point_el", None))}
#: rate-loop outputs used for the steady-motion start (not in :data:`OUTPUTS`)
RATE_OUTPUTS = ("enc_rate_az", "enc_rate_el")
#: largest dropped share of the noise-increment covariance trace before the plant refuses: 70 x
#: the largest share measured at the longest period over plants drawn from the report's ranges
#: (1.4e-8); a noise standard deviation moves by at most half of it (5e-7), far below the
#: scatter of any statistic the tools report
NOISE_TAIL_TOL = 1.0e-6
#: reference speed (m/s) for the (unused, zero-gain) gust filter of a plant without wind
_NO_WIND_FILTER_SPEED = 1.0
#: outputs computed every step (:data:`OUTPUTS` up to the gust torques)
N_STEP_OUTPUTS = 4


class Plant:
    """Exactly discretised rate loop plus wind-filter states for one mean wind speed.

    :param rate_loop: the rate loop (python-control ``StateSpace`` with inputs ``r_a, r_e,
        Tw_az, Tw_el`` and the outputs of :data:`OUTPUTS` / :data:`RATE_OUTPUTS`), e.g.
        ``default_model().rate_loop`` or :func:`dss14_env.model.uncertainty.perturbed_rate_loop`
    :param loads: calibrated wind loads (:func:`dss14_env.wind.loads.default_wind_loads`)
    :param wind_speed: mean wind speed ``U`` in m/s (0 = no wind)
    :param dt: control period in s (> 0)
    :param params: hydraulic parameters the rate loop was built with (for the record)
    :param xel_scale: ``cos(E)`` of the structure model's elevation angle ``E``: the
        cross-elevation pointing output of a rigid azimuth rotation ``theta`` is
        ``xel_scale * theta`` (:meth:`dss14_env.model.structure.Structure.output_matrices`)
    :param encoders: what the encoder outputs measure (:data:`ENCODER_OUTPUTS`): ``"drive"``
        the drive angles, ``"axis"`` the structure's pointing angles as axis angles (az:
        ``point_xel / xel_scale``, el: ``point_el``); the steady-motion start holds the
        chosen encoders at zero
    :raises ValueError: on a bad speed or period, if ``dt`` is so long that the 4-direction
        noise factor would drop more than :data:`NOISE_TAIL_TOL` of the noise, or if the
        discretised plant is not finite
    """

    def __init__(self, rate_loop: ct.StateSpace, loads: WindLoads, wind_speed: float, dt: float,
                 params: Mapping[str, float] | None = None, *, xel_scale: float, encoders: str = "drive"
                 ) -> None:
        if not (math.isfinite(wind_speed) and wind_speed >= 0.0):
            raise ValueError(f"wind_speed must be a finite speed >= 0 m/s, got {wind_speed!r}")
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a positive finite period in s, got {dt!r}")
        if not (math.isfinite(xel_scale) and 0.0 < xel_scale <= 1.0):
            raise ValueError(f"xel_scale must be cos(E) in (0, 1], got {xel_scale!r}")
        if encoders not in ENCODER_OUTPUTS:
            raise ValueError(f"encoders must be one of {', '.join(ENCODER_OUTPUTS)}, got {encoders!r}")
        self.encoders = encoders
        self.wind_speed = float(wind_speed)
        self.dt = float(dt)
        self.params = dict(params or {})
        self.xel_scale = float(xel_scale)
        self.loads = loads
        il, ol = list(rate_loop.input_labels), list(rate_loop.output_labels)
        A_r = np.asarray(rate_loop.A, float)
        B_r = np.asarray(rate_loop.B, float)[:, [il.index("r_a"), il.index("r_e")]]
        B_w = np.asarray(rate_loop.B, float)[:, [il.index("Tw_az"), il.index("Tw_el")]]
        C_r = np.asarray(rate_loop.C, float)
        rows = [ol.index(o) for o in OUTPUTS[:4] + RATE_OUTPUTS]
        nr = A_r.shape[0]

        windy = self.wind_speed > 0.0
        filt = loads.gust_filter(self.wind_speed if windy else _NO_WIND_FILTER_SPEED)
        A_f, G_f, C_f = (np.asarray(m, float) for m in (filt.A, filt.B, filt.C))
        nw = A_f.shape[0]
        c_ref = float(max(np.max(np.abs(loads.c_front)), np.max(np.abs(loads.c_side))))
        #: reference gust gain g_0(U), N*m per m/s (0 without wind)
        self.g0 = (loads.cfg.air_density * self.wind_speed * loads.dish_area * loads.cfg.dish_diameter
                   * c_ref) if windy else 0.0
        n = nr + 2 * nw
        A = np.zeros((n, n))
        A[:nr, :nr] = A_r
        A[:nr, nr:nr + nw] = self.g0 * B_w[:, [0]] @ C_f
        A[:nr, nr + nw:] = self.g0 * B_w[:, [1]] @ C_f
        A[nr:nr + nw, nr:nr + nw] = A_f
        A[nr + nw:, nr + nw:] = A_f
        B = np.zeros((n, 4))  # [r_a, r_e, T_mean_az, T_mean_el]
        B[:nr, :2], B[:nr, 2:] = B_r, B_w
        G = np.zeros((n, 2))  # [G_a, G_e]
        G[nr:nr + nw, 0], G[nr + nw:, 1] = G_f[:, 0], G_f[:, 0]
        C = np.zeros((len(OUTPUTS) + len(RATE_OUTPUTS), n))
        C[[0, 1, 2, 3, 6, 7], :nr] = C_r[rows]
        for row, (out, factor) in enumerate(ENCODER_OUTPUTS[encoders]):
            C[row, :nr] = C_r[ol.index(out)] / (self.xel_scale if factor == "xel" else 1.0)
        C[4, nr:nr + nw] = self.g0 * C_f[0]
        C[5, nr + nw:] = self.g0 * C_f[0]
        A, BG, C, scale = balance(A, np.hstack([B, G]), C)
        B, G = BG[:, :4], BG[:, 4:]

        #: number of rate-loop states, of filter states per copy, of joint states
        self.n_rate, self.n_wind, self.n = nr, nw, n
        #: continuous balanced realisation: state matrix, command / mean-torque / noise inputs
        self.A, self.B_r, self.B_T, self.G_a, self.G_e = A, B[:, :2], B[:, 2:], G[:, [0]], G[:, [1]]
        #: output matrix (rows :data:`OUTPUTS`) and encoder-rate rows (:data:`RATE_OUTPUTS`)
        self.C, self.C_rate = C[:len(OUTPUTS)].copy(), C[len(OUTPUTS):].copy()
        #: state scaling of the balanced realisation: x_raw = scale * x
        self.state_scale = scale

        Ad, Bd, _ = discretize(A, B, self.dt)
        if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(Bd))):
            raise ValueError(f"the plant at U = {self.wind_speed:g} m/s, dt = {self.dt:g} s, parameters "
                             f"{self.params or 'nominal'} is not finite")
        self.Ad, self.Bd_r, self.Bd_T = Ad, Bd[:, :2], Bd[:, 2:]
        self.L_a, self.L_e, self.noise_tail = self._noise_factors()
        self.noise_rank = self.L_a.shape[1]

        # stationary filter state (one copy, unit kappa), in balanced coordinates of copy a
        P_f = linalg.solve_continuous_lyapunov(A_f, -G_f @ G_f.T)
        self.filter_factor = noise_factor(P_f) / scale[nr:nr + nw, None]
        self._copy_ratio = scale[nr:nr + nw] / scale[nr + nw:]  # balanced x_e from balanced x_a
        self._episode_steps: dict = {}  # episode_step's results by direction
        self._steady = self._steady_state_operator()

    # ------------------------------------------------------------------ construction helpers
    def _noise_factors(self) -> tuple[np.ndarray, np.ndarray, float]:
        A, Ga, Ge, dt = self.A, self.G_a, self.G_e, self.dt
        Qaa = van_loan(A, Ga @ Ga.T, dt)
        Qee = van_loan(A, Ge @ Ge.T, dt)
        Qae = van_loan(A, Ga @ Ge.T, dt)
        Q = np.block([[Qaa, Qae], [Qae.T, Qee]])
        lam, V = np.linalg.eigh(0.5 * (Q + Q.T))
        lam, V = lam[::-1], V[:, ::-1]
        k = self.n_wind
        total = float(np.sum(np.clip(lam, 0.0, None)))
        tail = float(np.sum(np.clip(lam[k:], 0.0, None)) / total) if total > 0 else 0.0
        if tail > NOISE_TAIL_TOL:
            raise ValueError(f"dt = {dt} s is too long for the {k}-direction noise factor "
                             f"(drops {tail:.2e} of the noise variance); use a shorter dt")
        L = V[:, :k] * np.sqrt(np.clip(lam[:k], 0.0, None))
        return L[:self.n].copy(), L[self.n:].copy(), tail

    def _steady_state_operator(self) -> np.ndarray:
        """Linear map ``[x_wind (8), T_mean (2), v (2)] -> [x_rate (60), r (2)]`` of the
        steady motion at encoder rate ``v`` with the encoders at zero (wind states frozen).
        """
        nr, n = self.n_rate, self.n
        Arr, Arw = self.A[:nr, :nr], self.A[:nr, nr:]
        Br, BT = self.B_r[:nr], self.B_T[:nr]
        Cenc, Crate = self.C[:2, :nr], self.C_rate[:, :nr]
        # unknowns [x_r (nr), r (2), d (nr)]: A x + B r - d = -(Arw xw + BT T), A d = 0,
        # C_enc x = 0, C_rate x = v
        K = np.zeros((2 * nr + 4, 2 * nr + 2))
        K[:nr, :nr], K[:nr, nr:nr + 2], K[:nr, nr + 2:] = Arr, Br, -np.eye(nr)
        K[nr:2 * nr, nr + 2:] = Arr
        K[2 * nr:2 * nr + 2, :nr], K[2 * nr + 2:, :nr] = Cenc, Crate
        R = np.zeros((2 * nr + 4, (n - nr) + 4))
        R[:nr, :n - nr], R[:nr, n - nr:n - nr + 2] = -Arw, -BT
        R[2 * nr + 2:, n - nr + 2:] = np.eye(2)
        w = 1.0 / np.linalg.norm(K, axis=1)  # row equilibration: K spans 12 decades otherwise
        col = 1.0 / np.linalg.norm(K, axis=0)
        sol, *_ = linalg.lstsq(K * w[:, None] * col[None, :], R * w[:, None], lapack_driver="gelsy")
        sol *= col[:, None]
        scale = np.maximum(np.maximum(np.abs(R).max(axis=0), np.abs(K).max() * np.abs(sol).max(axis=0)),
                           np.finfo(float).tiny)
        resid = float(np.max(np.abs(K @ sol - R).max(axis=0) / scale))
        if resid > 1e-9:
            raise RuntimeError(f"steady-motion start: residual {resid:.2e} (rate loop not in the "
                               "expected form)")
        return sol[:nr + 2]

    # ------------------------------------------------------------------ per-episode helpers
    def filter_state(self, kappa: np.ndarray, xi: np.ndarray) -> np.ndarray:
        """Both filter copies ``[x_a, x_e]`` (balanced) from one stationary draw.

        :param kappa: direction factors ``(..., 2)``
        :param xi: standard normal draws ``(..., n_wind)``
        :return: ``(..., 2 n_wind)``
        """
        xa1 = xi @ self.filter_factor.T  # unit-kappa copy a, balanced
        kap = np.asarray(kappa, float)
        return np.concatenate([kap[..., :1] * xa1, kap[..., 1:2] * xa1 * self._copy_ratio], axis=-1)

    def steady_start(self, x_wind: np.ndarray, t_mean: np.ndarray, rate: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """State and held rate command of steady motion at encoder rate ``rate``.

        The rate loop is put in the steady state that moves both encoders at ``rate`` (rad/s)
        from zero under the constant torque ``T_mean + C_gust x_wind`` (the gust frozen at its
        start value); the filter states are ``x_wind``.

        :param x_wind: filter states ``(..., 8)`` (balanced, from :meth:`filter_state`)
        :param t_mean: mean torques ``(..., 2)``, N*m
        :param rate: encoder rates ``(..., 2)``, rad/s
        :return: ``(x0, r0)``: joint states ``(..., n)`` and rate commands ``(..., 2)`` (rad/s)
        """
        p = np.concatenate([x_wind, t_mean, rate], axis=-1)
        sol = p @ self._steady.T
        nr = self.n_rate
        return np.concatenate([sol[..., :nr], x_wind], axis=-1), sol[..., nr:nr + 2]

    def kappa(self, direction: float) -> np.ndarray:
        """Direction factors ``[kappa_az, kappa_el] = g(U, theta) / g_0(U)`` (zeros without wind)."""
        if self.g0 == 0.0:
            return np.zeros(2)
        return self.loads.gust_gain(self.wind_speed, direction) / self.g0

    def mean_torque(self, direction: float) -> np.ndarray:
        """Mean wind torques ``[Tw_az, Tw_el]`` in N*m (zeros without wind)."""
        if self.wind_speed == 0.0:
            return np.zeros(2)
        return self.loads.mean_torque(self.wind_speed, direction)

    def one_copy_projection(self, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Maps between the joint state and the 64-state form of one direction.

        Within an episode the two filter copies stay proportional (``x_a = kappa_az x_f``,
        ``x_e = kappa_el x_f``), so the joint state lies in the range of ``T`` and the one-copy
        state is ``u = P x`` with ``P T = I``; ``P Ad T``, ``P Bd``, ``C T`` are the exact
        discretisation of the 64-state plant ``[x_r, x_f]`` (the single environment steps it).

        :param kappa: direction factors (zeros without wind)
        :return: ``(T, P)``, shapes ``(n, n - n_wind)`` and ``(n - n_wind, n)``
        """
        nr, nw, n = self.n_rate, self.n_wind, self.n
        k0, k1 = (float(v) for v in kappa)
        if k0 == 0.0 and k1 == 0.0:
            k0 = k1 = 1.0  # no gust: the filter states stay zero whatever the map
        T = np.zeros((n, nr + nw))
        T[:nr, :nr] = np.eye(nr)
        T[nr:nr + nw, nr:] = k0 * np.eye(nw)
        T[nr + nw:, nr:] = k1 * np.diag(self._copy_ratio)
        P = np.zeros((nr + nw, n))
        P[:nr, :nr] = np.eye(nr)
        if abs(k0) >= abs(k1):
            P[nr:, nr:nr + nw] = np.eye(nw) / k0
        else:
            P[nr:, nr + nw:] = np.diag(1.0 / self._copy_ratio) / k1
        return T, P

    def noise_matrix(self, kappa: np.ndarray) -> np.ndarray:
        """Noise factor ``L = kappa_az L_a + kappa_el L_e`` ``(n, 4)`` of one direction."""
        return kappa[0] * self.L_a + kappa[1] * self.L_e

    def episode_step(self, kappa: np.ndarray, t_mean: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What the single environment steps an episode of one direction with, made once per
        direction (:data:`EPISODE_STEPS_KEPT` kept) and shared, read-only, by its episodes:
        ``(M^T, T, P, C T)`` -- :meth:`episode_map`'s map transposed and C-contiguous (the
        scalar step's form, ``input @ M^T``), its maps between the joint and the one-copy state,
        and the outputs of the one-copy state.

        :param kappa: direction factors (:meth:`kappa`)
        :param t_mean: mean wind torques, N*m (:meth:`mean_torque`)
        """
        key = (np.asarray(kappa, float).tobytes(), np.asarray(t_mean, float).tobytes())
        kept = self._episode_steps.get(key)
        if kept is None:
            if len(self._episode_steps) >= EPISODE_STEPS_KEPT:
                self._episode_steps.clear()
            M, T, P = self.episode_map(kappa, t_mean)
            kept = (np.ascontiguousarray(M.T), T, P, self.C @ T)
            for a in kept:
                a.flags.writeable = False
            self._episode_steps[key] = kept
        return kept

    @single_threaded
    def episode_map(self, kappa: np.ndarray, t_mean: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fused one-step map of one episode in the 64-state one-copy form (the single env).

        ``[u+; y+] = M [r_a, r_e, 1, xi, u]``: ``u = P x`` the one-copy state
        (:meth:`one_copy_projection`), ``r`` the held rate command, ``xi`` the step's standard
        normals, ``y`` the first :data:`N_STEP_OUTPUTS` outputs at the step's end; the constant
        input carries the held mean torque.  Exact: the same discretisation as
        :attr:`batch_step_matrix` restricted to the episode's direction.  Computed with one BLAS
        thread (:func:`dss14_env.core.threads.single_threaded`): the same bits whatever the
        caller's threads.

        :param kappa: direction factors (:meth:`kappa`)
        :param t_mean: mean wind torques, N*m (:meth:`mean_torque`)
        :return: ``(M, T, P)``: ``M`` of shape ``(m + N_STEP_OUTPUTS, 3 + k + m)`` with
            ``m = n - n_wind`` and ``k`` the noise rank, and the maps of
            :meth:`one_copy_projection`
        """
        T, P = self.one_copy_projection(kappa)
        m, k = P.shape[0], self.noise_rank
        h = 3 + k
        M = np.zeros((m + N_STEP_OUTPUTS, h + m))
        M[:m, :2] = P @ self.Bd_r
        M[:m, 2] = P @ (self.Bd_T @ np.asarray(t_mean, float))
        M[:m, 3:h] = P @ self.noise_matrix(kappa)
        M[:m, h:] = P @ self.Ad @ T
        M[m:] = (self.C[:N_STEP_OUTPUTS] @ T) @ M[:m]
        return M, T, P

    @cached_property
    def batch_step_matrix(self) -> np.ndarray:
        """Transposed fused map of the vector env (computed once, with one BLAS thread):
        ``[x+, y+] = [x, r, T_mean, kappa_az xi, kappa_el xi] @ M^T``.
        """
        return _batch_step_matrix(self)

    @cached_property
    def vector_step_matrix(self) -> np.ndarray:
        """:attr:`batch_step_matrix` without the gust-torque outputs (not observed), contiguous:
        the vector env's step map ``[x+, y+] = [x, r, T_mean, kappa_az xi, kappa_el xi] @ M``,
        ``y`` the first :data:`N_STEP_OUTPUTS` outputs; shape ``(n + 4 + 2 k, n + 4)``.
        """
        return np.ascontiguousarray(self.batch_step_matrix[:, :self.n + N_STEP_OUTPUTS])

    def __repr__(self) -> str:
        return (f"Plant(U={self.wind_speed:.3g} m/s, dt={self.dt:g} s, n={self.n}, "
                f"params={self.params or 'nominal'}, encoders={self.encoders})")


@single_threaded
def _batch_step_matrix(p: Plant) -> np.ndarray:
    top = np.hstack([p.Ad, p.Bd_r, p.Bd_T, p.L_a, p.L_e])
    return np.vstack([top, p.C @ top]).T.copy()


#: directions whose :meth:`Plant.episode_step` a plant keeps (a wind-direction grid's size)
EPISODE_STEPS_KEPT = 16


# ---------------------------------------------------------------------- one episode's step
def step_block(M: np.ndarray, x0: np.ndarray, y0: np.ndarray, steps: int) -> np.ndarray:
    """The step buffers of ``steps`` steps of an episode map ``M`` (:meth:`Plant.episode_map`),
    one row per step and one more: row ``j`` is ``z = [r_a, r_e, 1, xi, u, y]``, step ``j``'s
    input ``[r, 1, xi, u]`` followed by the outputs ``y`` of the step before, which wrote
    ``[u, y]``.  Row 0 holds the one-copy start state ``x0`` and its outputs ``y0``; the noise
    columns ``xi`` are filled a block of steps at a time, so that a step writes only its rate
    command.  :func:`block_views` makes the views the steps read and write
    (:mod:`dss14_env.envs.fused`).
    """
    n_in = M.shape[1]
    B = np.zeros((steps + 1, n_in + N_STEP_OUTPUTS))
    B[:, 2] = 1.0
    B[0, n_in - x0.shape[0]:n_in] = x0
    B[0, n_in:] = y0
    return B


def block_views(B: np.ndarray, m: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per step ``j`` of a :func:`step_block` ``B`` of an episode with ``m`` one-copy states:
    ``(input_j [r, 1, xi, u], [u, y] of row j + 1)``, views, so that ``input_j @ M^T`` is written
    in place into the next row (one matrix-vector product per step, no copies), where the step
    reads its outputs (:func:`dss14_env.envs.fused.after_one`).
    """
    n_in = B.shape[1] - N_STEP_OUTPUTS
    return [(B[j, :n_in], B[j + 1, n_in - m:]) for j in range(B.shape[0] - 1)]


# ---------------------------------------------------------------------- plants of one model
class PlantFactory:
    """The discretised plants of one calibrated model, built on demand and kept.

    Holds the model, the wind loads calibrated on it and its plants (least recently used
    first out beyond ``cache_size``).  Build one with :meth:`from_model_config` or take the
    shared one of a configuration file from :data:`PLANT_FACTORIES`.

    :param model: calibrated servo model (:func:`dss14_env.model.build_model`)
    :param loads: wind loads calibrated on that model
        (:func:`dss14_env.wind.loads.calibrate_wind_loads`)
    :param source: the model configuration file (None: the shipped default)
    :param cache_size: plants kept
    :param recalibrated: whether ``loads`` were refitted to Table 4 on ``model`` (True) or are
        the shipped coefficients (False)
    """

    def __init__(self, model: DSS14Model, loads: WindLoads, source: str | None = None,
                 cache_size: int = 64, recalibrated: bool = False) -> None:
        self.model = model
        self.loads = loads
        self.source = source
        self.recalibrated = bool(recalibrated)
        self.cache_size = int(cache_size)
        #: cos(E) of the structure model's elevation angle (cross-elevation of an az rotation)
        self.xel_scale = math.cos(model.cfg.structure.elevation_angle)
        self._plants: OrderedDict = OrderedDict()

    @classmethod
    def from_model_config(cls, path: str | Path, recalibrate_wind: bool | None = None) -> PlantFactory:
        """Build the model of a configuration file (a few seconds; :data:`PLANT_FACTORIES`
        keeps the result per file) with the shipped wind-load coefficients, or with
        coefficients refitted to [R] Table 4 on it.

        :param path: model YAML file or the name of a shipped one
        :param recalibrate_wind: refit the wind loads to Table 4 on this model; None: the
            file's ``recalibrate_wind`` key (default false)
        :raises ConfigError: a bad model configuration
        :raises WindCalibrationError: a refit that cannot meet Table 4's accepted ranges
        """
        return cls.from_config(load_model_config(path), recalibrate_wind)

    @classmethod
    def from_config(cls, cfg: ModelConfig, recalibrate_wind: bool | None = None) -> PlantFactory:
        """Build the model of a loaded configuration (:meth:`from_model_config` without reading
        the file).
        """
        model = build_model(cfg)
        refit = cfg.recalibrate_wind if recalibrate_wind is None else bool(recalibrate_wind)
        loads = calibrate_wind_loads(model) if refit else default_wind_loads()
        return cls(model, loads, source=str(cfg.path), recalibrated=refit)

    @property
    def wind_loads(self) -> str:
        """Where the wind-load coefficients come from (the reset info's ``wind_loads``):
        ``"shipped"`` or ``"refitted to Table 4"``.
        """
        return "refitted to Table 4" if self.recalibrated else "shipped"

    def plant(self, wind_speed: float, dt: float, params: Mapping[str, float] | None = None,
              encoders: str = "drive") -> Plant:
        """The plant for a mean wind speed, period, parameter set and encoders (built once per
        key).

        :param wind_speed: mean wind speed, m/s (0 = no wind)
        :param dt: control period, s
        :param params: hydraulic parameters (SI, names of
            :data:`dss14_env.model.uncertainty.SWEEP_PARAMS`) replacing the nominal ones
        :param encoders: what the encoders measure (:data:`ENCODER_OUTPUTS`)
        """
        key = (tuple(sorted((k, float(v)) for k, v in params.items())) if params else (), float(wind_speed),
               float(dt), encoders)
        plant = self._plants.get(key)
        if plant is not None:
            self._plants.move_to_end(key)
            return plant
        plant = _build_plant(self, float(wind_speed), float(dt), params, encoders)
        self._plants[key] = plant
        if len(self._plants) > self.cache_size:
            self._plants.popitem(last=False)
        return plant

    def check_params(self, params: Mapping[str, float], source: str = "params") -> dict[str, float]:
        """``params`` checked against the model's ranges (its configuration's ``range``).

        :param source: where ``params`` came from, for the message
            (:meth:`dss14_env.envs.config.EnvConfig.source_of`)
        :raises ValueError: ``<source>: field 'params.<name>': must lie in the range ...``
        """
        out = {}
        for name, value in params.items():
            if name not in SWEEP_PARAMS:
                raise ValueError(f"{source}: field 'params': must name parameters of "
                                 f"{', '.join(SWEEP_PARAMS)}, got {name!r}")
            lo, hi = self.model.cfg.params[name].range
            v = float(value)
            if not lo <= v <= hi:
                raise ValueError(f"{source}: field 'params.{name}': must lie in the range [{lo:g}, {hi:g}] "
                                 f"(SI) of the model {self.source or 'configs/model.yaml'}, got {value!r}")
            out[name] = v
        return out

    def draw_params(self, rng: np.random.Generator) -> ParamDraw:
        """A stable draw of the uncertain parameters of this model and the draws rejected
        before it (:func:`dss14_env.model.uncertainty.draw_params`).
        """
        return draw_params(rng, model=self.model)

    def __len__(self) -> int:
        return len(self._plants)

    def __repr__(self) -> str:
        return (f"PlantFactory(source={self.source or 'default'!s}, wind_loads={self.wind_loads}, "
                f"plants={len(self._plants)})")

    def __deepcopy__(self, memo: dict) -> PlantFactory:
        return self  # the model and loads never change; its plants are immutable

    def __reduce__(self) -> tuple:
        """Pickled by reference: the shipped model's factory, or the one of a model file (built
        again, or found in :data:`PLANT_FACTORIES`, on loading).
        """
        if self is default_plant_factory():
            return (default_plant_factory, ())
        if self.source is None:
            raise TypeError("a PlantFactory built from model objects cannot be pickled; build it from a "
                            "model file (PlantFactory.from_model_config) to pickle environments on it")
        return (_factory_of_file, (self.source, self.recalibrated))


class PlantFactories:
    """Plant factories per model configuration file: the models a process has built.

    Keyed by the file's resolved path and content (an edited file is built anew) and the
    wind-load choice; each content is parsed once.  One instance, :data:`PLANT_FACTORIES`,
    serves the environments; :meth:`clear` frees its models.
    """

    def __init__(self) -> None:
        self._factories: dict[tuple[str, str, bool], PlantFactory] = {}
        self._configs: dict[tuple[str, str], ModelConfig] = {}  # parsed files by path and content

    def get(self, model_config: str | Path | None = None,
            recalibrate_wind: bool | None = None) -> PlantFactory:
        """The factory of a model configuration file (None: the shipped default model, whose
        shipped coefficients are its Table 4 fit).

        :param recalibrate_wind: see :meth:`PlantFactory.from_model_config`
        :raises ConfigError: the file is missing or its configuration is bad
        """
        if model_config is None:
            return default_plant_factory()
        path = config_path(model_config).resolve()
        file = (str(path), hashlib.sha256(path.read_bytes()).hexdigest())
        cfg = self._configs.get(file)
        if cfg is None:
            cfg = self._configs[file] = load_model_config(path)
        refit = cfg.recalibrate_wind if recalibrate_wind is None else bool(recalibrate_wind)
        factory = self._factories.get((*file, refit))
        if factory is None:
            factory = self._factories[(*file, refit)] = PlantFactory.from_config(cfg, refit)
        return factory

    def clear(self) -> None:
        """Forget every model built from a file (the default model stays)."""
        self._factories.clear()
        self._configs.clear()

    def __len__(self) -> int:
        return len(self._factories)


@single_threaded
def _build_plant(f: PlantFactory, wind_speed: float, dt: float, params: Mapping[str, float] | None,
                 encoders: str = "drive") -> Plant:
    """A plant of ``f``'s model, built with one BLAS thread (the same bits whatever the caller's
    threads, :mod:`dss14_env.core.threads`).
    """
    rl = perturbed_rate_loop(f.model, dict(params)) if params else f.model.rate_loop
    return Plant(rl, f.loads, wind_speed, dt, params, xel_scale=f.xel_scale, encoders=encoders)


#: the plant factories of this process, per model configuration file
PLANT_FACTORIES = PlantFactories()


@lru_cache(maxsize=1)
def default_plant_factory() -> PlantFactory:
    """The factory of the shipped model (:func:`dss14_env.model.default_model` and
    :func:`dss14_env.wind.loads.default_wind_loads`), built once per process.
    """
    return PlantFactory(default_model(), default_wind_loads())


def _factory_of_file(path: str, recalibrated: bool = False) -> PlantFactory:
    return PLANT_FACTORIES.get(path, recalibrated)


def resolve_factory(model_config: Any, recalibrate_wind: bool | None = None) -> PlantFactory:
    """The plant factory an environment's ``model_config`` argument names.

    :param model_config: None (the shipped model), a model YAML path or shipped name, or a
        :class:`PlantFactory`
    :param recalibrate_wind: None (the model file's choice, default: the shipped
        coefficients) or a bool: refit the wind loads to Table 4 on a model file
    :raises ValueError: anything else (``ConfigError`` for a bad file)
    """
    if recalibrate_wind is not None and not isinstance(recalibrate_wind, (bool, np.bool_)):
        raise ValueError(f"recalibrate_wind must be None, True or False, got {recalibrate_wind!r}")
    if isinstance(model_config, PlantFactory):
        if recalibrate_wind is not None and bool(recalibrate_wind) != model_config.recalibrated:
            raise ValueError(f"recalibrate_wind={recalibrate_wind} contradicts the given PlantFactory "
                             f"(wind loads {model_config.wind_loads})")
        return model_config
    if model_config is None or isinstance(model_config, (str, Path)):
        return PLANT_FACTORIES.get(model_config, None if recalibrate_wind is None else bool(recalibrate_wind))
    raise ValueError(f"model_config must be None, a model YAML path or a PlantFactory, got "
                     f"{type(model_config).__name__}")


def get_plant(wind_speed: float, dt: float, params: Mapping[str, float] | None = None) -> Plant:
    """The plant of the shipped model for a mean speed, period and parameter set
    (``default_plant_factory().plant(...)``).
    """
    return default_plant_factory().plant(wind_speed, dt, params)
