"""What a test run collects: the examples in the package's docstrings, and the ``quick`` tier.

* Only modules with an example (``>>>``) are collected for their doctests, so that collecting
  them imports no more than the examples need: a module without one (e.g.
  ``agents/vec_env.py``, which subclasses stable-baselines3's classes and so imports torch) is
  left to the tests that import it.
* ``pytest -m quick`` runs the tests of :data:`QUICK_FILES` (marked ``quick`` here, in one
  place): the core's configuration and statistics, the model's blocks, the environment's
  interface and reward; about 15 s of CPU time.  With ``-m quick`` alone nothing else is
  collected (collecting the whole suite imports torch and stable-baselines3 and costs more
  than the tier itself).
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent
#: the folders whose modules are collected for their doctests only
DOCTEST_DIRS = tuple(ROOT / d for d in ("dss14_env", "agents", "baselines"))
#: the test files of the ``quick`` tier
QUICK_FILES = frozenset(ROOT / "tests" / f"{name}.py" for name in (
    "test_schema", "test_config", "test_stats", "test_blocks", "test_env", "test_env_reward"))


def _quick_only(config: pytest.Config) -> bool:
    return (config.getoption("markexpr", "") or "").strip() == "quick"


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """Skip a package module that has no example, and under ``-m quick`` every file outside
    :data:`QUICK_FILES`; decide nothing for anything else.
    """
    if collection_path.suffix != ".py" or collection_path.name in ("__init__.py", "conftest.py"):
        return None
    if _quick_only(config):
        return True if collection_path not in QUICK_FILES else None
    if not any(collection_path.is_relative_to(d) for d in DOCTEST_DIRS):
        return None
    return True if ">>>" not in collection_path.read_text(encoding="utf-8") else None


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests of :data:`QUICK_FILES` ``quick``."""
    for item in items:
        if item.path in QUICK_FILES:
            item.add_marker(pytest.mark.quick)
