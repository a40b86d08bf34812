"""Stability margins and limit cycles of a controller in the benchmark's holds.

The controller (a policy folder loaded with the project's safe loader, or the report's PI
``pi_kp1``) is linearised at the hold's operating point and closed with the environment's
plant; the loop is broken at the rate command of one axis at a time.

1. **Operating point.**  A long hold (``--seconds``, default 200 s) in the hold's wind: the
   mean observation over the scored window (after the 5-s warm-up).
2. **The controller's linear response.**  The controller is a black box from observations to
   actions, with whatever memory it keeps (a policy's history and filters, a PI's integrator).
   It is fed the mean observation for ``--taps`` steps (its memory settles there), then one
   entry is moved by ``+-delta`` for one step and back: the central difference of the actions
   over the next ``--taps`` steps is its impulse response from that entry, ``h[m]`` (2 x 12
   per lag).  The response is modelled as a finite impulse response plus its final value held
   (an integrator: ``H(z) = sum_m (h[m] - h_inf) z^-m + h_inf / (1 - z^-1)``, ``h_inf`` the
   mean of the last quarter of the taps), so that a controller with integral action is
   represented too; what is left of the response at the last taps after removing ``h_inf``
   (``tail``) measures the model's truncation.
3. **The plant and the observation map.**  The environment's exactly discretised plant
   (:class:`dss14_env.envs.plant.Plant`, the same matrices the environment steps) from the
   applied rates ``r`` to the encoders ``y``, and the observation as the environment forms it
   in a hold (command constant): errors ``-y / error_scale``, error rates ``-(y_k - y_k-1) /
   (error_scale dt)``, encoder readings ``y`` in deg, the previous applied rate ``r_k-1 /
   rate_limit``; the command entries 4-7 are constant.  Quantisation and the limiter are left
   out (linearisation).
4. **Margins.**  ``K(z) = action_scale H(z) O(z)`` maps the applied rates to the next ones;
   the loop of axis ``i`` broken at its rate command is ``L_i = -(K_ii + K_ij K_ji / (1 -
   K_jj))`` with the other axis's loop closed, and ``L_i = -K_ii`` with it open (the
   convention of the report's single-axis analysis, docs/model.md).  Gain and phase margins
   come from ``control.stability_margins`` on its frequency response (1e-3 Hz to the Nyquist
   frequency); the full two-axis loop's stability from the eigenvalues of its state matrix.
5. **Limit cycles.**  In the long hold and in a calm hold (no wind) the applied rate command
   of each axis, mean removed, Hann window: the dominant spectral peak above
   ``--min-hz``, its frequency, its amplitude (deg/s, a sinusoid's) and the share of the
   command's variance within +-10 % of that frequency (near 1: a periodic oscillation).

    python scripts/policy_margins.py --policy agents/policies/ppo_general \
        --out docs/results/policy_margins.json
    python scripts/policy_margins.py --policy pi_kp1 --out pi_margins.json
    python scripts/policy_margins.py --out docs/results/policy_margins.json --render docs/stability.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control as ct
import gymnasium as gym
import numpy as np
from scipy import sparse
from scipy.sparse import linalg as sparse_linalg

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.baselines.base import Controller
from dss14_env.baselines.pi import PIController
from dss14_env.core.units import DEG, MDEG
from dss14_env.envs.presets import PRESETS

#: the holds analysed
HOLDS = ("hold_front", "hold_side")
AXES = ("az", "el")
#: observation entries that vary in a hold (4-7, the command, are constant)
MOVING = (0, 1, 2, 3, 8, 9, 10, 11)
#: a final value of the impulse response below this share of its largest tap is none
HELD_FLOOR = 1e-4
#: the generated table's markers and head in docs/stability.md
MARK_START, MARK_END = "<!-- margins:start -->", "<!-- margins:end -->"
TABLE_HEAD = ("| controller, hold | axis | gain margin, dB | phase margin, ° | gain crossover, Hz | "
              "peak sensitivity | largest closed-loop pole | command's dominant peak in the hold / calm: "
              "Hz, amplitude °/s, share |\n|---|---|---|---|---|---|---|---|")
#: closed loops up to this many states get all their eigenvalues; larger ones the six largest (ARPACK)
DENSE_EIG = 1500


# ------------------------------------------------------------------ the controller's response
@dataclass(frozen=True)
class ControllerResponse:
    """A controller's linear response at an operating point: actions per observation entry.

    :param h: impulse response ``(taps, 2, 12)``, action per unit of observation entry
    :param h_inf: the final value held ``(2, 12)`` (integral action), zero where it is below
        :data:`HELD_FLOOR` of the largest ``|h|`` or below 10 times its ripple over the last
        quarter of the taps
    :param tail: largest ``|h[m] - h_inf|`` over the last quarter of the taps, relative to the
        largest ``|h|``: what the model truncates
    """

    h: np.ndarray
    h_inf: np.ndarray
    tail: float

    def freq(self, z: np.ndarray) -> np.ndarray:
        """``H(z)`` ``(len(z), 2, 12)``."""
        g = self.h - self.h_inf
        powers = z[:, None] ** -np.arange(g.shape[0])[None, :]
        return np.einsum("fm,mij->fij", powers, g) + self.h_inf / (1.0 - 1.0 / z)[:, None, None]


def _actions(ctrl: Controller, obs: np.ndarray, k0: int, entry: int, delta: float, n: int) -> np.ndarray:
    """Actions ``(n, 2)`` from step ``k0`` on, the observation ``obs`` throughout except entry
    ``entry`` moved by ``delta`` at step ``k0``."""
    ctrl.reset(seed=0)
    out = np.empty((n, 2))
    for k in range(k0 + n):
        o = obs.copy()
        if k == k0:
            o[entry] += delta
        a = np.asarray(ctrl.act(o.astype(np.float32)), float)
        if k >= k0:
            out[k - k0] = a
    return out


def controller_response(ctrl: Controller, obs: np.ndarray, deltas: np.ndarray, taps: int,
                        entries: Sequence[int] = MOVING) -> ControllerResponse:
    """Central-difference impulse response of ``ctrl`` about the constant observation ``obs``.

    :param deltas: the step of each of the 12 entries (observation units)
    :param taps: lags measured (the memory settles for as many steps first)
    """
    h = np.zeros((taps, 2, obs.size))
    for j in entries:
        plus = _actions(ctrl, obs, taps, j, deltas[j], taps)
        minus = _actions(ctrl, obs, taps, j, -deltas[j], taps)
        h[:, :, j] = (plus - minus) / (2.0 * deltas[j])
    last = h[-max(taps // 4, 1):]
    scale = float(np.max(np.abs(h))) or 1.0
    h_inf = last.mean(axis=0)
    # integral action only where the response settles on a value clearly above its own ripple
    # and the differences' rounding (float32 networks): else a finite (decayed) response
    h_inf[(np.abs(h_inf) <= HELD_FLOOR * scale) | (np.abs(h_inf) <= 10.0 * last.std(axis=0))] = 0.0
    tail = float(np.max(np.abs(last - h_inf))) / scale
    return ControllerResponse(h, h_inf, tail)


def explained_share(resp: ControllerResponse, observed: np.ndarray, actions: np.ndarray) -> list[float]:
    """Share of each action's variance in a recorded hold that the linear model explains,
    ``1 - var(a - a_lin) / var(a)`` (means removed), ``a_lin`` the model driven by the
    recorded observations about their mean.
    """
    d = observed - observed.mean(axis=0)
    g = resp.h - resp.h_inf
    lin = np.zeros_like(actions)
    for m in range(g.shape[0]):
        lin[m:] += d[:d.shape[0] - m] @ g[m].T
    lin += np.cumsum(d, axis=0) @ resp.h_inf.T
    out = []
    for i in range(actions.shape[1]):
        a, b = actions[:, i] - actions[:, i].mean(), lin[:, i] - lin[:, i].mean()
        out.append(float(1.0 - np.var(a - b) / np.var(a)) if np.var(a) > 0 else math.nan)
    return out


# ------------------------------------------------------------------ plant and observation map
@dataclass(frozen=True)
class ObservationLoop:
    """The plant from the applied rates to the observation in a hold, ``s+ = A s + B r``,
    ``o = C s`` (state ``[x, y_prev, r_prev]``), and the action scale (rad/s per action).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    action_scale: float
    dt: float

    def freq(self, z: np.ndarray) -> np.ndarray:
        """``O(z)`` ``(len(z), 12, 2)``."""
        eye = np.eye(self.A.shape[0])
        return np.stack([self.C @ np.linalg.solve(zi * eye - self.A, self.B) for zi in z])


def observation_loop(env: Any) -> ObservationLoop:
    """The observation map of a DSS14 environment's hold (see the module docstring, step 3)."""
    u = env.unwrapped
    cfg = u.config
    plant = u.plants.plant(0.0, cfg.dt, cfg.params or None, cfg.encoders)
    n = plant.n_rate  # the rate loop's states: the gust filters' (after them) are not driven by r
    Ad, Bd, Cy = plant.Ad[:n, :n], plant.Bd_r[:n], plant.C[:2, :n]
    eu = cfg.error_scale_mdeg * MDEG
    A = np.zeros((n + 4, n + 4))
    A[:n, :n] = Ad
    A[n:n + 2, :n] = Cy
    B = np.zeros((n + 4, 2))
    B[:n] = Bd
    B[n + 2:] = np.eye(2)
    C = np.zeros((12, n + 4))
    C[0:2, :n] = -Cy / eu
    C[2:4, :n] = -Cy / (eu * cfg.dt)
    C[2:4, n:n + 2] = np.eye(2) / (eu * cfg.dt)
    C[8:10, :n] = Cy / DEG
    C[10:12, n + 2:] = np.eye(2) / (cfg.rate_limit_deg_s * DEG)
    return ObservationLoop(A, B, C, cfg.action_scale_deg_s * DEG, cfg.dt)


# ------------------------------------------------------------------ margins
def _margins(L: np.ndarray, omega: np.ndarray, dt: float) -> dict[str, float]:
    """Gain margin (dB), phase margin (deg), stability margin and their frequencies (Hz) of the
    loop gain ``L`` sampled at ``omega`` (rad/s)."""
    gm, pm, sm, wpc, wgc, wms = ct.stability_margins(ct.frd(L, omega, dt=dt))

    def hz(w: float) -> float:
        return float(w) / (2 * math.pi) if np.isfinite(w) else math.nan

    return {"gain_margin_db": 20 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf,
            "phase_margin_deg": float(pm), "phase_crossover_hz": hz(wpc),
            "gain_crossover_hz": hz(wgc), "stability_margin": float(sm),
            "peak_sensitivity": 1.0 / float(sm) if sm > 0 else math.inf, "stability_margin_hz": hz(wms)}


def loop_gains(resp: ControllerResponse, loop: ObservationLoop, f_hz: np.ndarray) -> np.ndarray:
    """``K(f)`` ``(len(f), 2, 2)``: applied rates of step ``k`` to the controller's next rates."""
    z = np.exp(2j * math.pi * f_hz * loop.dt)
    return loop.action_scale * np.einsum("fij,fjk->fik", resp.freq(z), loop.freq(z))


def axis_margins(K: np.ndarray, f_hz: np.ndarray, dt: float) -> dict[str, Any]:
    """Per axis: margins with the other axis's loop closed and open."""
    omega = 2 * math.pi * f_hz
    out = {}
    for i, ax in enumerate(AXES):
        j = 1 - i
        closed = -(K[:, i, i] + K[:, i, j] * K[:, j, i] / (1.0 - K[:, j, j]))
        out[ax] = {"other_axis_closed": _margins(closed, omega, dt),
                   "other_axis_open": _margins(-K[:, i, i], omega, dt)}
    return out


def closed_loop_poles(resp: ControllerResponse, loop: ObservationLoop) -> np.ndarray:
    """The largest eigenvalues (by magnitude, at least six) of the two-axis loop (plant,
    observation map, controller model), largest first.

    The controller's realisation keeps a delay line of the observation entries it responds to
    and an accumulator of those with integral action, nothing else (an entry it ignores would
    add a pole at 0 or 1 that no loop can move).
    """
    taps = resp.h.shape[0]
    g = resp.h - resp.h_inf
    used = [j for j in range(g.shape[2]) if np.any(g[:, :, j])]
    held = [j for j in range(g.shape[2]) if np.any(resp.h_inf[:, j])]
    Cu, Ch = loop.C[used], loop.C[held]
    m, mh, ns = len(used), len(held), loop.A.shape[0]
    nd = (taps - 1) * m  # the used entries of o_k-1 .. o_k-taps+1
    N = ns + nd + mh     # + the accumulated held entries up to k-1
    # a_k = G0 o_k + sum_m G_m o_k-m + h_inf (q_k-1 + o_k);  r_k = action_scale a_k;  o_k = C s_k
    Ca = np.zeros((2, N))
    Ca[:, :ns] = g[0][:, used] @ Cu + resp.h_inf[:, held] @ Ch
    for k in range(1, taps):
        Ca[:, ns + (k - 1) * m: ns + k * m] = g[k][:, used]
    Ca[:, ns + nd:] = resp.h_inf[:, held]
    Ca *= loop.action_scale
    top = np.zeros((ns, N))
    top[:, :ns] = loop.A
    top += loop.B @ Ca
    blocks = [sparse.csr_matrix(top)]
    if nd:
        blocks.append(sparse.hstack([sparse.csr_matrix(Cu), sparse.csr_matrix((m, N - ns))]))
        blocks.append(sparse.hstack([sparse.csr_matrix((nd - m, ns)), sparse.eye(nd - m),
                                     sparse.csr_matrix((nd - m, m + mh))]))
    if mh:
        blocks.append(sparse.hstack([sparse.csr_matrix(Ch), sparse.csr_matrix((mh, nd)), sparse.eye(mh)]))
    A = sparse.vstack(blocks).tocsr()
    if N <= DENSE_EIG:
        lam = np.linalg.eigvals(A.toarray())
    else:
        lam = sparse_linalg.eigs(A, k=6, which="LM", return_eigenvectors=False, maxiter=20 * N, tol=1e-10)
    return lam[np.argsort(-np.abs(lam))]


def closed_loop_radius(resp: ControllerResponse, loop: ObservationLoop) -> float:
    """Spectral radius of the two-axis loop (:func:`closed_loop_poles`)."""
    return float(np.abs(closed_loop_poles(resp, loop)[0]))


def pole_table(lam: np.ndarray, dt: float, n: int = 6) -> list[dict[str, float]]:
    """The ``n`` largest poles as magnitude and frequency (Hz), one of each conjugate pair."""
    rows: list[dict[str, float]] = []
    for v in lam:
        if v.imag < 0 and np.any(np.isclose(lam, v.conjugate())):
            continue
        f = float(abs(np.angle(v)) / (2 * math.pi * dt))
        rows.append({"magnitude": float(abs(v)), "frequency_hz": f})
        if len(rows) == n:
            break
    return rows


# ------------------------------------------------------------------ long holds
def long_hold(ctrl: Controller, env: Any, seed: int, steps: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observations ``(steps, 12)``, actions ``(steps, 2)`` and applied rate commands
    ``(steps, 2)`` (deg/s) of one hold."""
    cfg = env.unwrapped.config
    obs, _ = env.reset(seed=seed)
    ctrl.reset(seed=seed)
    observed, actions, rates = np.empty((steps, 12)), np.empty((steps, 2)), np.empty((steps, 2))
    for k in range(steps):
        observed[k] = obs
        actions[k] = ctrl.act(obs)
        obs, _, term, trunc, _ = env.step(actions[k].astype(np.float32))
        rates[k] = np.asarray(obs[10:12], float) * cfg.rate_limit_deg_s
        if term:
            raise RuntimeError(f"{ctrl.name}: the hold terminated at step {k}")
    return observed, actions, rates


def limit_cycle(r: np.ndarray, dt: float, min_hz: float) -> dict[str, dict[str, float]]:
    """The dominant periodic component of each axis's command ``r`` ``(n, 2)`` (deg/s)."""
    n = r.shape[0]
    w = np.hanning(n)
    f = np.fft.rfftfreq(n, dt)
    out = {}
    for i, ax in enumerate(AXES):
        x = r[:, i] - r[:, i].mean()
        X = np.fft.rfft(x * w)
        p = np.abs(X) ** 2
        band = f >= min_hz
        k = int(np.flatnonzero(band)[np.argmax(p[band])])
        near = band & (np.abs(f - f[k]) <= 0.1 * f[k])
        out[ax] = {"frequency_hz": float(f[k]), "amplitude_deg_s": float(2.0 * np.abs(X[k]) / w.sum()),
                   "share_of_variance": float(p[near].sum() / p[band].sum()) if p[band].sum() > 0 else 0.0,
                   "rms_deg_s": float(x.std())}
    return out


# ------------------------------------------------------------------ one controller
def make_controller(name: str, env: Any) -> Controller:
    """``pi_kp1`` (the report's PI) or a policy folder (the project's safe loader)."""
    if name == "pi_kp1":
        return PIController(env, "kp1")
    from dss14_env.agents.policy import load_policy

    return load_policy(name, env=env)


def analyse(name: str, seconds: float = 200.0, taps: int = 512, seed: int = 7000,
            rel_delta: float = 0.05, min_hz: float = 0.02,
            env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Margins and limit cycles of one controller in the two holds (and a calm hold)."""
    result: dict[str, Any] = {}
    for hold in HOLDS + ("hold_calm",):
        preset = PRESETS["hold_front" if hold == "hold_calm" else hold]
        kwargs = dict(env_kwargs or {})
        if hold == "hold_calm":
            kwargs["wind_speed_kmh"] = 0.0
        env = gym.make(preset.env_id, **kwargs)
        dt = env.unwrapped.config.dt
        steps = int(round(seconds / dt))
        ctrl = make_controller(name, env)
        observed, actions, rates = long_hold(ctrl, env, seed, steps)
        k0 = int(round(preset.warmup_s / dt))
        scored = observed[k0:]
        row: dict[str, Any] = {"seconds": seconds, "seed": seed,
                               "limit_cycle": limit_cycle(rates[k0:], dt, min_hz)}
        if hold != "hold_calm":
            op = scored.mean(axis=0)
            deltas = rel_delta * np.maximum(scored.std(axis=0), 1e-6)
            resp = controller_response(ctrl, op, deltas, taps)
            loop = observation_loop(env)
            poles = closed_loop_poles(resp, loop)
            fr = np.logspace(-3, math.log10(0.5 / dt) - 1e-3, 4000)
            row.update({"operating_point": op.tolist(), "deltas": deltas.tolist(), "taps": taps,
                        "tail": resp.tail,
                        "explained_share": explained_share(resp, observed, actions),
                        "integral_action_entries": np.flatnonzero(np.abs(resp.h_inf).max(axis=0)).tolist(),
                        "closed_loop_spectral_radius": float(abs(poles[0])),
                        "margins": axis_margins(loop_gains(resp, loop, fr), fr, dt),
                        "closed_loop_largest_poles": pole_table(poles, dt)})
        env.close()
        result[hold] = row
    return result


def _f(x: float, fmt: str) -> str:
    return "–" if x is None or not math.isfinite(x) else format(x, fmt)


def table(result: Mapping[str, Any]) -> str:
    """The markdown table of a result file (rows: controller, hold, axis; loop at a time)."""
    lines = [TABLE_HEAD]
    for name, c in result["controllers"].items():
        calm = c["hold_calm"]["limit_cycle"]
        for hold in HOLDS:
            r = c[hold]
            pole = r["closed_loop_largest_poles"][0]
            for ax in AXES:
                m = r["margins"][ax]["other_axis_closed"]
                lc = [r["limit_cycle"][ax], calm[ax]]
                peaks = " / ".join(f"{x['frequency_hz']:.2f}, {x['amplitude_deg_s']:.1e}, "
                                   f"{x['share_of_variance']:.2f}" for x in lc)
                lines.append(f"| {Path(name).name}, {hold} | {ax} | {_f(m['gain_margin_db'], '.1f')} | "
                             f"{_f(m['phase_margin_deg'], '.1f')} | {_f(m['gain_crossover_hz'], '.3f')} | "
                             f"{_f(m['peak_sensitivity'], '.2f')} | {pole['magnitude']:.4f} at "
                             f"{pole['frequency_hz']:.2f} Hz | {peaks} |")
    return "\n".join(lines) + "\n"


def render(result_path: Path, doc: Path) -> bool:
    """Write :func:`table` of ``result_path`` between ``doc``'s markers; True if it changed."""
    text = doc.read_text(encoding="utf-8")
    start, end = text.index(MARK_START) + len(MARK_START) + 1, text.index(MARK_END)
    new = text[:start] + table(json.loads(result_path.read_text(encoding="utf-8"))) + text[end:]
    doc.write_text(new, encoding="utf-8")
    return new != text


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", action="append",
                   help="pi_kp1 or a policy folder (repeatable)")
    p.add_argument("--render", type=Path, metavar="DOC",
                   help="only write the table of --out (an existing result) into DOC's margins section")
    p.add_argument("--seconds", type=float, default=200.0)
    p.add_argument("--taps", type=int, default=512)
    p.add_argument("--seed", type=int, default=7000)
    p.add_argument("--out", type=Path, required=True)
    a = p.parse_args(argv)
    if a.render is not None:
        render(a.out, a.render)
        return 0
    if not a.policy:
        p.error("--policy is required (or --render)")
    if not (a.seconds >= 10.0 and a.taps >= 4):
        p.error(f"--seconds must be >= 10 and --taps >= 4, got {a.seconds} and {a.taps}")
    for name in a.policy:
        if name != "pi_kp1" and not Path(name).is_dir():
            p.error(f"--policy {name!r}: neither pi_kp1 nor a policy folder")
    out = {"method": __doc__.split("\n\n")[0], "seed": a.seed, "taps": a.taps,
           "command": "python scripts/policy_margins.py " + " ".join(sys.argv[1:] if argv is None else argv),
           "controllers": {name: analyse(name, a.seconds, a.taps, a.seed) for name in a.policy}}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=1, default=float) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
