"""scripts/bench_env_speed.py: the vector env against the raw matmul of its plant size, the
ratios taken per repeat, and --check's exit status following the targets (no timing asserted)."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "bench_env_speed.py"


def test_the_speed_script_reports_its_ratios_and_checks_them(tmp_path: Path) -> None:
    out = tmp_path / "speed.json"
    cmd = [sys.executable, str(SCRIPT), "--steps", "200", "--vec-steps", "5", "--num-envs", "8",
           "--repeats", "3", "--clock", "cpu", "--blas-threads", "1", "--ppo-steps", "0", "--json", str(out),
           "--check"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    res = json.loads(out.read_text())
    for env_id, r in res["ratio_to_matmul"].items():
        mm, vec = res["matmul"][env_id], res["vector"][env_id]
        n, k, m = mm["shape"]
        assert n == 8 and k > m > 60  # (N x K) @ (K x n+4): the state, the inputs, 4 outputs
        # the ratio is per repeat: vector rate over the matmul rate of the same repeat
        assert [round(a / b, 12) for a, b in zip(vec["values"], mm["values"], strict=True)] == \
            [round(x, 12) for x in r["values"]]
        assert r["target"] == 0.5 and r["meets_target"] == (r["ci95"][0] >= 0.5)
        # which step ran is recorded: compiled where numba is installed
        assert vec["compiled"] is (importlib.util.find_spec("numba") is not None)
    assert "ppo_env_share" not in res and res["compile_s"] > 0.0  # --ppo-steps 0: not measured
    missed = [s for kind in ("ratio_to_pendulum", "ratio_to_matmul") for s in res[kind].values()
              if not s["meets_target"]]
    assert done.returncode == (1 if missed else 0), done.stderr
    assert ("targets missed" in done.stdout) == bool(missed)
