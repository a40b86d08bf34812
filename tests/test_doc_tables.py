"""The result tables in docs/model.md and docs/wind.md are the rendering of the
committed ``docs/results/reproduce_metrics.json`` (nothing typed by hand).

``tests/test_reproduce.py::test_committed_results_match_the_code`` checks that the committed
file is what the code gives; this file checks that the documents show that file.  Fix a
failure with ``python scripts/render_reproduce_tables.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dss14_env.reproduce import doc_blocks, fill_blocks, find_blocks

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "reproduce_metrics.json"
EXPECTED_BLOCKS = {
    "docs/model.md": {"reproduce-table", "reproduce-loop-figures", "reproduce-poles",
                      "reproduce-bandwidth-rigid", "reproduce-viscosity"},
    "docs/wind.md": {"reproduce-wind-coefficients", "reproduce-wind-drive", "reproduce-table4"},
}


@pytest.fixture(scope="module")
def blocks() -> dict[str, str]:
    return doc_blocks(json.loads(RESULTS.read_text()))


@pytest.mark.parametrize("doc", sorted(EXPECTED_BLOCKS))
def test_document_tables_are_the_committed_results(blocks: dict, doc: str) -> None:
    found = {name: body for name, body in find_blocks((ROOT / doc).read_text()).items()
             if name.startswith("reproduce-")}  # other generated tables are checked elsewhere
    assert set(found) == EXPECTED_BLOCKS[doc]
    for name, body in found.items():
        assert body == blocks[name], f"{doc}: block {name} differs from the committed results"


def test_readme_table_has_every_accepted_row_inside(blocks: dict) -> None:
    table = blocks["reproduce-table"]
    assert "**NO**" not in table
    assert table.count("| yes |") >= 10


def test_fill_and_find_blocks_roundtrip() -> None:
    text = "a\n<!-- x:start -->\nold\n<!-- x:end -->\nb\n<!-- y:start -->\nkeep\n<!-- y:end -->\n"
    new = fill_blocks(text, {"x": "new\n"})
    assert find_blocks(new) == {"x": "new\n", "y": "keep\n"}
    assert new.startswith("a\n<!-- x:start -->\nnew\n<!-- x:end -->\nb\n")


def test_render_script_check_mode_passes() -> None:
    import subprocess
    import sys
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "render_reproduce_tables.py"), "--check"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
