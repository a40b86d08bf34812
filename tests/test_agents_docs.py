"""The python examples of docs/rl.md run, each on its own, in a temporary folder.

Blocks fenced as ```python run; a block may end with ``# prints: <text>`` (then the text must
appear in what it printed).  Blocks fenced as ```py need files of the reader's own (an old
stable-baselines3 run) and are shown only.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "rl.md"
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)
BLOCKS = _BLOCK.findall(PAGE.read_text()) if PAGE.is_file() else []


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_rl_doc_example_runs(index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    code = BLOCKS[index]
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"docs/rl.md[{index}]", "exec"), {"__name__": "__docs__"})
    for expected in re.findall(r"# prints: (.+)$", code, re.M):
        assert expected.strip() in out.getvalue(), out.getvalue()


def test_the_page_has_examples() -> None:
    assert len(BLOCKS) >= 3
