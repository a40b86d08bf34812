"""The command line's error handling: one line on stderr, status 2 for bad input and OS errors,
130 for an interruption."""

from __future__ import annotations

import argparse

import pytest

from dss14_env.cli import run_command


def _args(func) -> argparse.Namespace:
    return argparse.Namespace(command="demo", func=func, argv=[])


@pytest.mark.parametrize("exc,fragment", [
    (ValueError("bad --seeds: -1"), "bad --seeds: -1"),
    (PermissionError(13, "Permission denied", "/x/results.json"), "/x/results.json: Permission denied"),
    (FileExistsError(17, "File exists", "bench_out"), "bench_out: File exists"),
    (KeyError("unknown gain set 'kp2'"), "unknown gain set 'kp2'"),
    (RuntimeError("no stable parameter draw\nin 200 tries"), "no stable parameter draw in 200 tries"),
])
def test_expected_failures_are_one_line_status_2(exc: Exception, fragment: str, capsys) -> None:
    def boom(args):
        raise exc

    assert run_command(_args(boom)) == 2
    err = capsys.readouterr().err
    assert err.startswith("dss14 demo: error: ") and fragment in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_interrupt_is_status_130(capsys) -> None:
    def stop(args):
        raise KeyboardInterrupt

    assert run_command(_args(stop)) == 130
    assert "stopped (SIGINT)" in capsys.readouterr().err


def test_a_bug_keeps_its_traceback() -> None:
    def bug(args):
        raise ZeroDivisionError("a bug")

    with pytest.raises(ZeroDivisionError):
        run_command(_args(bug))


def test_reproduce_refuses_a_file_as_out_before_any_work(tmp_path, capsys) -> None:
    from dss14_env.cli import main

    target = tmp_path / "a_file"
    target.write_text("not a folder")
    assert main(["reproduce", "--out", str(target), "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert "is a file, not a folder" in err and err.count("\n") == 1
    assert target.read_text() == "not a folder"


def test_reproduce_refuses_earlier_results_without_overwrite(tmp_path, capsys) -> None:
    from dss14_env.cli import main
    from dss14_env.core.outdir import (
        atomic_write_bytes,
        atomic_write_text,
        prepare_output_dir,
        update_manifest,
    )
    from dss14_env.reproduce import OWNED_FILES

    prepare_output_dir(tmp_path, OWNED_FILES, command="reproduce")  # an earlier run: its files listed
    atomic_write_text(tmp_path / "metrics.json", "{}")
    atomic_write_bytes(tmp_path / "fig03_board_r_to_i.png", b"old")
    update_manifest(tmp_path)
    assert main(["reproduce", "--out", str(tmp_path), "--no-figures"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "metrics.json").read_text() == "{}"  # nothing touched


def test_reproduce_bad_config_named_before_any_work(tmp_path, capsys) -> None:
    from dss14_env.cli import main

    assert main(["reproduce", "--out", str(tmp_path / "o"), "--config", "no_such_model"]) == 2
    assert "no_such_model" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_atomic_writes_give_ordinary_file_modes(tmp_path) -> None:
    import os
    import stat

    from dss14_env.core.outdir import atomic_write_text

    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "results.json", "{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "results.json").stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]  # no temporary left behind


def test_reproduce_prints_the_readme_table_and_counts_figures_in_words(tmp_path, monkeypatch, capsys) -> None:
    from pathlib import Path

    from dss14_env import reproduce as R
    from dss14_env.cli import main

    def fake(out, model, figures=True, progress=False):
        Path(out, "metrics.json").write_text("{}")
        return {"markdown": "| `pi_pm45_gain_factor_drive_az` |", "table": "| labelled quantity |",
                "figures": ["fig01.png"], "failed": [], "metrics": {}}

    monkeypatch.setattr(R, "reproduce", fake)
    monkeypatch.setattr("dss14_env.model.assembly.default_model", lambda: None)
    assert main(["reproduce", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "| labelled quantity |" in out and "pi_pm45_gain_factor_drive_az" not in out
    assert "1 figure, metrics.json" in out


def test_version(capsys) -> None:
    from dss14_env import __version__
    from dss14_env.cli import main

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"dss14 {__version__}"
