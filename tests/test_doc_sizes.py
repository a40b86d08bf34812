"""The README fits on a few screens and every manual stays a manual: word limits counted as
``wc -w`` counts (runs of non-whitespace), generated tables included."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the most words of the README and of each manual in docs/
README_WORDS = 2500
MANUAL_WORDS = 6000
#: the most words of the architecture page (a walk through the house, not a manual)
ARCHITECTURE_WORDS = 1200


def words(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").split())


def test_readme_fits_its_limit_and_opens_with_the_three_commands() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert words(ROOT / "README.md") <= README_WORDS
    # the first screen: install, then the three commands, then the compact headline table
    marks = ("## Install", 'gym.make("DSS14-v0")', "dss14 train ppo", "dss14 bench --controllers pi_kp1 mpc",
             "<!-- bench-headline:start -->")
    order = [text.index(s) for s in marks]
    assert order == sorted(order)


@pytest.mark.parametrize("page", sorted(p.name for p in (ROOT / "docs").glob("*.md")))
def test_each_manual_fits_its_limit(page: str) -> None:
    assert words(ROOT / "docs" / page) <= MANUAL_WORDS, page


def test_the_architecture_page_fits_its_limit_and_draws_the_layers() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert words(ROOT / "docs" / "architecture.md") <= ARCHITECTURE_WORDS
    assert text.count("```mermaid") == 1
