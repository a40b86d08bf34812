"""Every JSON or YAML file the tools read back is capped in bytes before it is read: a huge
file (sparse here, so the test writes nothing) is refused with one line naming it, or counts
as no usable run, never read whole."""

from __future__ import annotations

from pathlib import Path

import pytest

from dss14_env.agents.campaign import check_saved_config, finished_run, resumable_checkpoint
from dss14_env.agents.config import load_config
from dss14_env.core.files import MAX_JSON_BYTES, read_json, read_text
from dss14_env.core.schema import MAX_CONFIG_BYTES


def _sparse(path: Path, size: int) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        fh.truncate(size)
    return path


@pytest.mark.parametrize("size", [MAX_JSON_BYTES + 1, 1 << 40])
def test_a_json_file_past_its_cap_is_refused_naming_it(tmp_path: Path, size: int) -> None:
    p = _sparse(tmp_path / "results.json", size)
    with pytest.raises(ValueError, match=rf"^{p}: longer than {MAX_JSON_BYTES} bytes"):
        read_json(p)


def test_text_at_the_cap_is_read_and_binary_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "a.yaml"
    p.write_bytes(b"x" * 16)
    assert read_text(p, 16) == "x" * 16
    p.write_bytes(b"\xff\xfe")
    with pytest.raises(ValueError, match="not UTF-8"):
        read_text(p, 16)


def test_a_huge_run_summary_or_config_is_no_finished_run(tmp_path: Path) -> None:
    cfg = load_config("ppo_smoke")
    run = tmp_path / "seed_0"
    _sparse(run / "train_summary.json", 1 << 40)
    _sparse(run / "config.yaml", 1 << 40)
    assert finished_run(cfg, run) is False
    assert resumable_checkpoint(cfg, run) is None


def test_resume_on_a_huge_config_names_the_folder(tmp_path: Path) -> None:
    _sparse(tmp_path / "config.yaml", MAX_CONFIG_BYTES + 1)
    with pytest.raises(ValueError, match="holds no campaign to continue"):
        check_saved_config(load_config("ppo_smoke"), tmp_path)
