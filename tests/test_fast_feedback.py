"""Fast feedback: collecting the docstring examples imports no torch (the examples that need
none), importing the command line imports none of the heavy libraries (a command's own modules
are imported inside the command), and the ``quick`` tier is registered."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: repository folder -> installed package
PACKAGES = {"dss14_env": "dss14_env", "agents": "dss14_env.agents", "baselines": "dss14_env.baselines"}


def _modules_with_examples() -> list[str]:
    """The modules the doctest collection imports (root ``conftest.py``: those with ``>>>``)."""
    mods = []
    for folder, package in PACKAGES.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            if ">>>" in path.read_text(encoding="utf-8") or path.name == "__init__.py":
                rel = path.relative_to(ROOT / folder).with_suffix("")
                parts = [p for p in rel.parts if p != "__init__"]
                mods.append(".".join([package, *parts]))
    return mods


def test_doctest_collection_imports_no_torch(tmp_path: Path) -> None:
    mods = _modules_with_examples()
    assert "dss14_env.agents.config" in mods and "dss14_env.agents.vec_env" not in mods
    code = ("import importlib, sys\n"
            f"for m in {mods!r}: importlib.import_module(m)\n"
            "print(sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                         timeout=300)  # away from the source tree: the installed package is imported
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout


#: libraries whose import costs seconds on a loaded machine: a command imports them when it runs
HEAVY = ("torch", "stable_baselines3", "sb3_contrib", "ray", "cvxpy", "numba", "control", "matplotlib",
         "scipy")


@pytest.mark.parametrize("backend", [None, "Agg"])
def test_importing_the_command_line_imports_no_heavy_library(tmp_path: Path, backend: str | None) -> None:
    """Also with ``MPLBACKEND`` naming an off-screen backend (as CI and headless users set it)."""
    code = ("import sys\nimport dss14_env.cli\n"
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    if backend is not None:
        env["MPLBACKEND"] = backend
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout


def test_quick_tier_is_registered_and_its_files_exist() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("root_conftest", ROOT / "conftest.py")
    root = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(root)
    assert '"quick: ' in (ROOT / "pyproject.toml").read_text()
    assert root.QUICK_FILES and all(p.is_file() for p in root.QUICK_FILES)


def test_the_off_screen_backends_passed_unchecked_are_matplotlibs() -> None:
    from matplotlib.backends.registry import BackendFilter, backend_registry

    import dss14_env

    assert dss14_env.OFF_SCREEN_BACKENDS == set(backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE))
