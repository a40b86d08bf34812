"""The code examples of the README and of every manual in ``docs/`` run, each on its own.

Every fenced ``python`` block is executed in a fresh namespace, in a temporary working folder;
a block that raises fails the test.  A block may end with a comment ``# prints: <text>``: then
``<text>`` must appear in what it printed.  A training budget ``.learn(total_timesteps=<N>``
runs shortened to :data:`SHORT_TIMESTEPS` (one rollout).  Blocks fenced as ```` ```py ```` need files
of the reader's own and are shown only.  A block that builds an environment on a user model
(``model_config``) calibrates a model and runs in the slow suite.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the README and every manual
PAGES = ["README.md"] + sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)
#: the training budget of an example as the test runs it
SHORT_TIMESTEPS = 64


def blocks(page: str) -> list[str]:
    return _BLOCK.findall((ROOT / page).read_text(encoding="utf-8"))


def _case(page: str, i: int, code: str):
    marks = [pytest.mark.slow] if "model_config" in code else []
    return pytest.param(page, i, id=f"{page}-{i}", marks=marks)


CASES = [_case(page, i, code) for page in PAGES for i, code in enumerate(blocks(page))]


@pytest.mark.parametrize("page,index", CASES)
def test_example_runs_standalone(page: str, index: int, tmp_path: Path,
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    code = re.sub(r"\.learn\(total_timesteps=[0-9_]+", f".learn(total_timesteps={SHORT_TIMESTEPS}",
                  blocks(page)[index])
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"{page}[{index}]", "exec"), {"__name__": "__docs__"})
    for expected in re.findall(r"^# prints: (.+)$", code, re.M):
        assert expected.strip() in out.getvalue(), out.getvalue()


@pytest.mark.parametrize("page", ["README.md", "docs/controllers.md", "docs/env.md", "docs/rl.md",
                                  "docs/scale.md"])
def test_pages_with_examples_keep_them(page: str) -> None:
    assert blocks(page), f"{page} lost its python examples"
