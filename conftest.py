"""Collection of the examples in the package's docstrings (``--doctest-modules``).

Only modules with an example (``>>>``) are collected for their doctests, so that collecting
them imports no more than the examples need: a module without one (e.g.
``agents/vec_env.py``, which subclasses stable-baselines3's classes and so imports torch) is
left to the tests that import it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent
#: the folders whose modules are collected for their doctests only
DOCTEST_DIRS = tuple(ROOT / d for d in ("dss14_env", "agents", "baselines"))


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """Skip a package module that has no example; decide nothing for anything else."""
    if (collection_path.suffix != ".py" or collection_path.name == "__init__.py"
            or not any(collection_path.is_relative_to(d) for d in DOCTEST_DIRS)):
        return None
    return True if ">>>" not in collection_path.read_text(encoding="utf-8") else None
