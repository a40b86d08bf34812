"""The code blocks of docs/controllers.md run, each on its own (fresh namespace, temporary
working folder); a block's ``# prints: <text>`` comment must appear in what it printed."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[1] / "docs" / "controllers.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", PAGE.read_text(encoding="utf-8"), flags=re.M | re.S)


def test_page_has_its_examples() -> None:
    assert len(BLOCKS) == 4


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_code_block_runs(index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    code = BLOCKS[index]
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"{PAGE.name} python block {index + 1}", "exec"), {"__name__": "__docs__"})
    for expected in re.findall(r"^# prints: (.+)$", code, flags=re.M):
        assert expected.strip() in out.getvalue(), out.getvalue()
