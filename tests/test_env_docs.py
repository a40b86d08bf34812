"""``docs/env.md``: its generated sections are the docstrings (and the speed results) as they are
now, and every registered id is listed (its code examples run in test_docs_examples.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import gymnasium as gym

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.presets import PRESETS, WRAPPED_IDS

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "env.md"


def _generator():
    spec = importlib.util.spec_from_file_location("gen_env_docs", ROOT / "scripts" / "gen_env_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_generated_sections_are_up_to_date() -> None:
    text = DOC.read_text()
    assert _generator().render(text) == text, "docs/env.md is out of date: run python scripts/gen_env_docs.py"


def test_a_changed_docstring_makes_the_check_fail(monkeypatch) -> None:
    gen = _generator()
    monkeypatch.setattr(gen.DSS14Env, "__doc__", DSS14Env.__doc__.replace("* v0: initial version.",
                                                                       "* v0: initial version; edited."))
    assert gen.render(DOC.read_text()) != DOC.read_text()


def test_every_registered_id_is_in_the_manual() -> None:
    ids = sorted(i for i in gym.registry if i.startswith("DSS14"))
    assert set(ids) == {p.env_id for p in PRESETS.values()} | set(WRAPPED_IDS)
    for env_id in ids:
        assert f"`{env_id}`" in DSS14Env.__doc__ and f"`{env_id}`" in DOC.read_text(), env_id
        assert f"`{env_id}`" in (ROOT / "README.md").read_text(), env_id
