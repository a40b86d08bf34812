"""The code blocks of docs/controllers.md run, in order, in one namespace (as a reader would)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "controllers.md"


def test_controllers_page_code_blocks_run(capsys: pytest.CaptureFixture) -> None:
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)
    assert len(blocks) == 4
    namespace: dict = {}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{DOC}: python block {i + 1}", "exec"), namespace)
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4
    # what the blocks print: the side wind read from the start command (90 deg), one design per
    # row of the tracking batch, the MPC's fast path without fallbacks, a stable closed loop
    assert namespace["ctrl"].info["design_wind"][1] == pytest.approx(1.5707963267948966)
    assert len(namespace["lqg"].info_batch["design_wind_direction_rad"]) == 4
    assert lines[2] == "osqp 0 []"
    assert lines[3].endswith("True")
