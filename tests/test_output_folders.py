"""Output folders: one command's run per folder, ownership from the manifest's file list only,
and a lock on a folder in use.

The scenarios are a user's: a bench pointed at a campaign's folder, a file of the user's
dropped among a run's files (whatever its time), two runs started into one ``--out``, a run
killed while holding its folder, a manifest edited by hand.
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dss14_env import cli
from dss14_env.bench import bench as B
from dss14_env.core.folderlock import LOCK_FILE, folder_locked
from dss14_env.core.outdir import (
    MANIFEST,
    OutputDirError,
    atomic_folder,
    atomic_write_text,
    prepare_output_dir,
    release_output_dir,
    update_manifest,
)

#: a campaign of one plant, one controller, one wind condition (a second or two)
CAMPAIGN = ["campaign", "--plants", "1", "--controllers", "pi_kp1", "--directions", "side",
            "--steps", "300", "--chunk-size", "1", "--no-progress", "--no-figures"]


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


@pytest.fixture
def no_bench(monkeypatch) -> list:
    """The bench's work replaced by a marker: what matters is whether it started."""
    started: list = []

    def run_plan(*a, **k):
        started.append(1)
        raise RuntimeError("the bench started")

    monkeypatch.setattr(B, "run_plan", run_plan)
    return started


@pytest.fixture(scope="module")
def campaign_folder(tmp_path_factory) -> Path:
    """A finished tiny campaign's folder (copied by the tests that change it)."""
    out = tmp_path_factory.mktemp("camp") / "c"
    assert cli.main(CAMPAIGN + ["--out", str(out)]) == 0
    return out


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


# ------------------------------------------------------------------ one folder, one command
def test_a_bench_never_writes_into_a_campaigns_folder(campaign_folder, tmp_path, capsys,
                                                      no_bench) -> None:
    out = _copy(campaign_folder, tmp_path / "c")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    for extra in ([], ["--overwrite"]):
        assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "--out", str(out)] + extra) == 2
        _one_line(capsys, str(out), "'dss14 campaign'", "'dss14 bench'")
    assert not no_bench and {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert cli.main(CAMPAIGN + ["--out", str(out), "--resume"]) == 0  # still the campaign's
    assert "0 chunks computed, 1 read back" in capsys.readouterr().out


def test_a_campaign_never_takes_a_bench_folder(tmp_path, capsys) -> None:
    out = tmp_path / "b"
    prepare_output_dir(out, B.OWNED_FILES, command=B.COMMAND)
    atomic_write_text(out / "results.json", '{"bench": 1}')
    release_output_dir(out)
    for extra in (["--resume"], ["--overwrite"]):
        assert cli.main(CAMPAIGN + ["--out", str(out)] + extra) == 2
        _one_line(capsys, str(out), "'dss14 bench'", "'dss14 campaign'")
    assert (out / "results.json").read_text() == '{"bench": 1}' and not (out / "chunks").exists()


# ------------------------------------------------------------------ ownership from the manifest only
def test_a_users_figure_in_a_campaign_folder_is_never_adopted(campaign_folder, tmp_path) -> None:
    out = _copy(campaign_folder, tmp_path / "c")
    (out / "cdf_x.png").write_bytes(b"mine")  # named like the campaign's figures, newer than it
    assert cli.main(CAMPAIGN + ["--out", str(out), "--resume"]) == 0
    assert "cdf_x.png" not in json.loads((out / MANIFEST).read_text())["files"]
    assert cli.main(CAMPAIGN + ["--out", str(out), "--overwrite"]) == 0
    assert (out / "cdf_x.png").read_bytes() == b"mine"


@pytest.mark.parametrize("age_s", [0, -3600])
def test_a_users_file_inside_the_chunks_is_refused_whatever_its_time(campaign_folder, tmp_path,
                                                                    capsys, age_s) -> None:
    out = _copy(campaign_folder, tmp_path / "c")
    mine = out / "chunks" / "notes.txt"
    mine.write_text("mine")
    if age_s:
        t = mine.stat().st_mtime + age_s
        os.utime(mine, (t, t))
    assert cli.main(CAMPAIGN + ["--out", str(out), "--overwrite"]) == 2
    _one_line(capsys, "no run's manifest", "chunks/notes.txt")
    assert mine.read_text() == "mine" and len(list(out.glob("chunks/chunk-*.json"))) == 1


def test_writers_list_their_files_before_writing(tmp_path) -> None:
    out = tmp_path / "run"
    prepare_output_dir(out, ("results.json", "checkpoints"), command="train")
    atomic_write_text(out / "results.json", "{}")
    (out / "checkpoints").mkdir()
    with atomic_folder(out / "checkpoints" / "10_steps") as tmp:
        listed = json.loads((out / MANIFEST).read_text())
        assert listed["folders"] == [tmp.relative_to(out).as_posix()]  # before a byte is in it
        atomic_write_text(tmp / "policy.pt", "w")
    (out / "checkpoints" / "later.txt").write_text("mine")  # the user's, newer than the run
    assert update_manifest(out) == ["checkpoints/10_steps/policy.pt", "results.json"]
    release_output_dir(out)
    with pytest.raises(OutputDirError, match="no run's manifest .*checkpoints/later.txt"):
        prepare_output_dir(out, ("results.json", "checkpoints"), overwrite=True, command="train")
    (out / "checkpoints" / "later.txt").unlink()
    prepare_output_dir(out, ("results.json", "checkpoints"), overwrite=True, command="train")
    assert sorted(p.name for p in out.iterdir()) == [LOCK_FILE, MANIFEST]
    release_output_dir(out)


def test_a_manifest_naming_a_path_outside_its_folder_is_named(tmp_path, capsys) -> None:
    out = tmp_path / "b"
    out.mkdir()
    for field, value in (("owned", "/etc/*"), ("files", "../elsewhere.json")):
        (out / MANIFEST).write_text(json.dumps({"format": "dss14-manifest-1", "command": "bench",
                                                field: [value]}))
        assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "--out", str(out)]) == 2
        _one_line(capsys, str(out / MANIFEST), f"field '{field}'", value)


def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch, no_bench) -> None:
    monkeypatch.chdir(tmp_path)
    assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "--out", ""]) == 2
    _one_line(capsys, "--out ''", "is empty")
    assert list(tmp_path.iterdir()) == [] and not no_bench


# ------------------------------------------------------------------ a lock on a folder in use
def _hold(folder: Path, pid: int, command: str) -> int:
    """Hold ``folder``'s lock as another run would (an open file description of its own)."""
    folder.mkdir(parents=True, exist_ok=True)
    fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.write(fd, json.dumps({"pid": pid, "host": "node7", "command": command,
                             "started_utc": "2026-01-01T00:00:00Z"}).encode())
    return fd


def test_a_folder_in_use_is_refused_naming_the_other_run(tmp_path, capsys, no_bench) -> None:
    out = tmp_path / "b"
    fd = _hold(out, 4242, "dss14 bench --out b")
    try:
        for extra in ([], ["--overwrite"]):
            assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "--out", str(out)] + extra) == 2
            _one_line(capsys, f"--out {out}", "in use by another run", "process 4242 on node7",
                      "dss14 bench --out b")
        assert cli.main(CAMPAIGN + ["--out", str(out)]) == 2
        _one_line(capsys, "in use by another run")
    finally:
        os.close(fd)
    assert not no_bench and sorted(p.name for p in out.iterdir()) == [LOCK_FILE]


def test_a_second_process_is_refused_while_the_first_runs(tmp_path) -> None:
    out = tmp_path / "b"
    prepare_output_dir(out, B.OWNED_FILES, command=B.COMMAND)  # this process runs a bench there
    code = ("import sys\nfrom dss14_env import cli\n"
            f"sys.exit(cli.main(['bench', '--quick', '--controllers', 'pi_kp1', '--out', {str(out)!r}]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and f"process {os.getpid()}" in r.stderr, r.stderr
    assert "'dss14 bench'" in r.stderr
    release_output_dir(out)
    assert not (out / LOCK_FILE).exists() and not folder_locked(out)


def test_a_dead_runs_lock_is_taken_over_and_a_run_releases_its_own(campaign_folder, tmp_path,
                                                                    capsys) -> None:
    out = _copy(campaign_folder, tmp_path / "c")
    fd = _hold(out, 999_999_999, "dss14 campaign --out c")
    os.close(fd)  # the holder died (SIGKILL): its lock file stays, the kernel dropped its lock
    assert (out / LOCK_FILE).exists()
    assert cli.main(CAMPAIGN + ["--out", str(out), "--resume"]) == 0
    assert not (out / LOCK_FILE).exists() and not folder_locked(out)
    assert cli.main(CAMPAIGN + ["--out", str(out), "--overwrite"]) == 0  # free again
