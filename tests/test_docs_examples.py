"""The code examples of the README and the manuals run, each on its own.

Every fenced ``python`` block of the pages below is executed in a fresh namespace, in a
temporary working folder; a block that raises fails the test.  A block may end with a comment
``# prints: <text>``: then ``<text>`` must appear in what it printed.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: pages whose python blocks run here (others test their own pages)
PAGES = ["README.md"]
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)


def blocks(page: str) -> list[str]:
    return _BLOCK.findall((ROOT / page).read_text())


CASES = [(page, i) for page in PAGES for i in range(len(blocks(page)))]


@pytest.mark.parametrize("page,index", CASES, ids=[f"{p}-{i}" for p, i in CASES])
def test_example_runs_standalone(page: str, index: int, tmp_path: Path, monkeypatch) -> None:
    code = blocks(page)[index]
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"{page}[{index}]", "exec"), {"__name__": "__docs__"})
    for expected in re.findall(r"^# prints: (.+)$", code, re.M):
        assert expected.strip() in out.getvalue(), out.getvalue()


def test_every_page_has_examples() -> None:
    assert all(blocks(p) for p in PAGES)
