"""The process environment cannot turn a working command into a failure: a ``MPLBACKEND`` that
names no backend is set aside (the figures are drawn off-screen), and an output encoding that
lacks σ or ± (``PYTHONIOENCODING=ascii``) writes escapes instead of reporting bad input.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = ["bench", "--quick", "--controllers", "pi_kp1", "--scenarios", "hold_front", "--no-sweep",
         "--episodes", "2", "--no-progress"]


@pytest.mark.parametrize("variable, value, extra", [
    ("MPLBACKEND", "nonsense", ["--no-figures"]),
    ("MPLBACKEND", "nonsense", []),
    ("PYTHONIOENCODING", "ascii", ["--no-figures"]),
])
def test_a_bench_finishes_whatever_the_environment_says(tmp_path: Path, variable: str, value: str,
                                                        extra: list[str]) -> None:
    out = tmp_path / "out"
    code = "import sys; from dss14_env.cli import main; sys.exit(main(sys.argv[1:]))"
    env = {**os.environ, variable: value}
    done = subprocess.run([sys.executable, "-c", code, *BENCH, *extra, "--out", str(out)], env=env,
                          capture_output=True, cwd=tmp_path, timeout=600)
    err = done.stderr.decode("utf-8", "replace")
    assert done.returncode == 0, err[-2000:]
    assert (out / "results.json").is_file() and "Traceback" not in err
    if variable == "MPLBACKEND":
        assert "MPLBACKEND='nonsense' names no matplotlib backend" in err
        assert bool(list(out.glob("*.png"))) == (not extra)
    else:
        assert "\\u03c3" in done.stdout.decode("ascii")  # σ as an escape
