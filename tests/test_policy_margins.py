"""scripts/policy_margins.py: the linearisation of a black-box controller, the observation map
and the margins, checked against what is known independently of them.

* The report's PI, identified as a black box, has the margins of the sampled PI's own transfer
  function (:func:`dss14_env.baselines.analysis.pi_as_linear`) on the same plant, and the
  continuous loop's phase margins of docs/model.md within the sampling's phase lag.
* The observation map predicts what the environment observes after a sequence of rate
  commands (calm, exact encoders).
* A known sinusoid in noise is found as the limit cycle; a known FIR controller is recovered.
"""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from dss14_env.baselines.analysis import pi_as_linear
from dss14_env.baselines.base import Controller
from dss14_env.baselines.pi import PIController

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "policy_margins.py"
_spec = importlib.util.spec_from_file_location("policy_margins", SCRIPT)
pm = importlib.util.module_from_spec(_spec)
sys.modules["policy_margins"] = pm  # its dataclasses look their module up
_spec.loader.exec_module(pm)

#: the continuous PI loops' phase margins az, el (kp 1, ki 0.3), docs/model.md's generated table
DOC_PHASE_MARGIN_DEG = (56.9, 62.0)


@pytest.fixture(scope="module")
def hold_env():
    env = gym.make("DSS14-HoldFront-v0")
    yield env
    env.close()


def _freq(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, z: np.ndarray) -> np.ndarray:
    eye = np.eye(A.shape[0])
    return np.stack([C @ np.linalg.solve(zi * eye - A, B) + D for zi in z])


def test_the_pi_identified_as_a_black_box_has_its_analytic_margins(hold_env) -> None:
    loop = pm.observation_loop(hold_env)
    ctrl = PIController(hold_env, "kp1")
    resp = pm.controller_response(ctrl, np.zeros(12), np.full(12, 1e-3), taps=16)
    assert resp.tail < 1e-6 and resp.h_inf[:, :2].any()  # integral action, found exactly
    f = np.logspace(-3, math.log10(24.9), 3000)
    black = pm.axis_margins(pm.loop_gains(resp, loop, f), f, loop.dt)
    # independent: the sampled PI's transfer function y -> r times the plant r -> y
    lin = pi_as_linear(loop.dt, "kp1")
    z = np.exp(2j * math.pi * f * loop.dt)
    n = loop.A.shape[0] - 4
    G = _freq(loop.A[:n, :n], loop.B[:n], loop.A[n:n + 2, :n], np.zeros((2, 2)), z)
    Kc = _freq(lin.Ac, lin.Bc, lin.Cc, lin.Dc, z)
    KG = np.einsum("fij,fjk->fik", Kc, G)
    for i, ax in enumerate(pm.AXES):
        ref = pm._margins(-KG[:, i, i], 2 * math.pi * f, loop.dt)
        got = black[ax]["other_axis_open"]
        assert got["phase_margin_deg"] == pytest.approx(ref["phase_margin_deg"], abs=0.01)
        assert got["gain_crossover_hz"] == pytest.approx(ref["gain_crossover_hz"], rel=1e-3)
        assert got["gain_margin_db"] == pytest.approx(ref["gain_margin_db"], abs=0.01)
        # the continuous loop's margin, less the sampling's lag (w dt / 2 at 0.12 Hz: 0.4 deg)
        assert got["phase_margin_deg"] == pytest.approx(DOC_PHASE_MARGIN_DEG[i], abs=1.0)
    assert pm.closed_loop_radius(resp, loop) < 1.0


def test_the_observation_map_predicts_the_environment(hold_env) -> None:
    env = gym.make("DSS14-HoldFront-v0", wind_speed_kmh=0.0, encoder_bits=None,
                   accel_limit_deg_s2=100.0)
    loop = pm.observation_loop(env)
    obs0, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.02, 0.02, (60, 2))
    s = np.zeros(loop.A.shape[0])
    s[-2:] = obs0[10:12] * env.unwrapped.config.rate_limit_deg_s * math.pi / 180  # r_-1
    worst = 0.0
    for a in actions:
        obs, *_ = env.step(a.astype(np.float32))
        s = loop.A @ s + loop.B @ (a * loop.action_scale)
        pred = loop.C @ s
        idx = list(pm.MOVING)
        worst = max(worst, float(np.max(np.abs(obs[idx] - obs0[idx] * [1, 1, 0, 0, 1, 1, 0, 0]
                                               - pred[idx]) / (np.abs(pred[idx]).max() + 1e-12))))
    env.close()
    assert worst < 1e-3


def test_a_sinusoid_in_noise_is_the_limit_cycle() -> None:
    dt, n = 0.02, 10000
    t = np.arange(n) * dt
    rng = np.random.default_rng(1)
    r = np.stack([2e-3 * np.sin(2 * math.pi * 1.7 * t) + 1e-4 * rng.standard_normal(n),
                  1e-4 * rng.standard_normal(n)], axis=1)
    lc = pm.limit_cycle(r, dt, 0.02)
    assert lc["az"]["frequency_hz"] == pytest.approx(1.7, abs=0.01)
    assert lc["az"]["amplitude_deg_s"] == pytest.approx(2e-3, rel=0.05)
    assert lc["az"]["share_of_variance"] > 0.9 > lc["el"]["share_of_variance"]


class _FIR(Controller):
    """a_k = 0.3 o_k[0] - 0.2 o_k-2[1] + 0.1 o_k-1[10] (a known finite response)."""

    def __init__(self) -> None:
        super().__init__("fir")
        self.reset()

    def reset(self, seed=None) -> None:
        super().reset(seed)
        self.past: list[np.ndarray] = [np.zeros(12)] * 2

    def act(self, observation: np.ndarray) -> np.ndarray:
        o = np.asarray(observation, float)
        a = 0.3 * o[0] - 0.2 * self.past[1][1] + 0.1 * self.past[0][10]
        self.past = [o, self.past[0]]
        return np.array([a, -a], np.float32)


def test_a_known_finite_response_is_recovered() -> None:
    resp = pm.controller_response(_FIR(), np.full(12, 0.01), np.full(12, 0.01), taps=8)
    want = np.zeros((8, 2, 12))
    want[0, 0, 0], want[2, 0, 1], want[1, 0, 10] = 0.3, -0.2, 0.1
    want[:, 1] = -want[:, 0]
    np.testing.assert_allclose(resp.h, want, atol=1e-5)
    assert not resp.h_inf.any() and resp.tail < 1e-5


def test_a_policy_that_is_not_a_folder_is_refused_in_one_line(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, str(SCRIPT), "--policy", str(tmp_path / "nope"),
                           "--out", str(tmp_path / "m.json")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "nope" in done.stderr and not (tmp_path / "m.json").exists()


def test_the_committed_table_is_the_committed_result(tmp_path: Path) -> None:
    doc = tmp_path / "stability.md"
    doc.write_text((ROOT / "docs" / "stability.md").read_text(encoding="utf-8"), encoding="utf-8")
    assert not pm.render(ROOT / "docs" / "results" / "policy_margins.json", doc)
