"""The README's command blocks (```` ```bash ````) work as written.

Every ``dss14`` line parses with the real parser and uses no option of earlier versions; no two
different runs share an output folder (a reader who runs a block line by line is never refused
for an earlier line's results); the ``--resume`` lines continue a line above.  The blocks also
run, shortened (fewer seeds, steps, plants and episodes; the substitutions are listed in
:func:`shorten`): one in the default suite, every block in the slow suite, in order, each
block in a fresh folder.  A line that joins a Ray cluster (``--address auto``) needs one and is
only parsed.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from dss14_env import cli

ROOT = Path(__file__).resolve().parents[1]
_BLOCK = re.compile(r"^```bash\n(.*?)^```", re.M | re.S)


def blocks() -> list[list[list[str]]]:
    """The README's bash blocks, each as its command lines split into words (comments and
    line continuations resolved).
    """
    out = []
    for body in _BLOCK.findall((ROOT / "README.md").read_text(encoding="utf-8")):
        text = body.replace("\\\n", " ")
        out.append([shlex.split(line, comments=True) for line in text.splitlines() if line.strip()])
    return out


def dss14_lines() -> list[list[str]]:
    """Every ``dss14`` command of the README, without the program name."""
    return [words[1:] for block in blocks() for words in block if words and words[0] == "dss14"]


@pytest.mark.parametrize("argv", dss14_lines(), ids=lambda a: " ".join(a)[:60])
def test_every_readme_command_parses_with_todays_options(argv: list[str]) -> None:
    args = cli.build_parser().parse_args(argv)
    cli.refuse_renamed(args)  # raises for an option of an earlier version


def test_no_two_readme_runs_share_an_output_folder() -> None:
    runs: dict[str, str] = {}
    for argv in dss14_lines():
        if "--resume" in argv or "--overwrite" in argv:
            continue
        out = cli.build_parser().parse_args(argv).out
        if out is None:  # a new timestamped folder each time
            continue
        line = " ".join(argv)
        assert runs.setdefault(out, line) == line, f"{line!r} and {runs[out]!r} both write {out}"


def test_every_resume_line_continues_a_line_above() -> None:
    for block in blocks():
        seen: list[list[str]] = []
        for words in block:
            if "--resume" in words:
                assert [w for w in words if w != "--resume"] in seen, words
            seen.append(words)


#: option -> value of the shortened runs
SHORT = {"--train-seeds": ["0-1"], "--plants": ["2"], "--episodes": ["2"]}
#: options added to the shortened runs of each command (unless the command gives them)
ADDED = {"train": [("--timesteps", "256")],
         "bench": [("--episodes", "2"), ("--sequential-episodes", "1"), ("--steps", "300"),
                   ("--no-sweep",)],
         "campaign": [("--steps", "300"), ("--chunk-size", "1"), ("--wind-speeds", "50"),
                      ("--directions", "front")]}


def shorten(argv: list[str]) -> list[str]:
    """A README command with fewer seeds, steps, plants and episodes (:data:`SHORT`,
    :data:`ADDED`); ``--quick`` runs as written, ``--num-cpus`` is capped at 2.
    """
    out = list(argv)
    for opt, value in SHORT.items():
        if opt in out:
            i = j = out.index(opt) + 1
            while j < len(out) and not out[j].startswith("--"):
                j += 1
            out[i:j] = value
    if "--num-cpus" in out:
        i = out.index("--num-cpus") + 1
        out[i] = str(min(2, int(out[i])))
    if "--quick" not in out:
        for opt, *value in ADDED.get(out[0], []):
            if opt not in out:
                out += [opt, *value]
    return out


def _run_block(block: list[list[str]], folder: Path, monkeypatch) -> None:
    monkeypatch.chdir(folder)
    for words in block:
        if words[:1] != ["dss14"]:
            continue
        if "--address" in words:  # a Ray cluster: not here
            continue
        argv = shorten(words[1:])
        assert cli.main(argv) == 0, " ".join(argv)


def test_the_shortening_keeps_the_command_and_shortens_its_counts() -> None:
    assert shorten(["train", "ppo", "--config", "ppo_plain", "--train-seeds", "0-4", "--out", "r"]) == [
        "train", "ppo", "--config", "ppo_plain", "--train-seeds", "0-1", "--out", "r", "--timesteps", "256"]
    assert shorten(["bench", "--scenarios", "step", "--episodes", "8", "--out", "s"]) == [
        "bench", "--scenarios", "step", "--episodes", "2", "--out", "s", "--sequential-episodes", "1",
        "--steps", "300", "--no-sweep"]
    assert shorten(["bench", "--quick"]) == ["bench", "--quick"]
    assert shorten(["campaign", "--plants", "200", "--ray", "--num-cpus", "4"])[:6] == [
        "campaign", "--plants", "2", "--ray", "--num-cpus", "2"]


def test_a_readme_bench_line_runs_shortened(tmp_path: Path, monkeypatch) -> None:
    """The default suite's one: the README's bench line with its own scenarios (step, slew)."""
    line = next(w for w in dss14_lines() if w[0] == "bench" and "--scenarios" in w and "step" in w)
    _run_block([["dss14", *line, "--no-figures", "--no-progress"]], tmp_path, monkeypatch)
    assert (tmp_path / line[line.index("--out") + 1] / "results.json").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("k", range(len(blocks())))
def test_every_readme_block_runs_shortened(k: int, tmp_path: Path, monkeypatch) -> None:
    _run_block(blocks()[k], tmp_path, monkeypatch)


def test_the_hyperparameter_file_the_readme_hands_rl_zoo3_exists() -> None:
    line = next(w for b in blocks() for w in b if w[:3] == ["python", "-m", "rl_zoo3.train"])
    inner = shlex.split(line[line.index("-conf") + 1].removeprefix("$(").removesuffix(")"))
    assert inner[:2] == ["python", "-m"]
    res = subprocess.run([sys.executable, *inner[1:]], capture_output=True, text=True, check=True)
    assert Path(res.stdout.strip()).is_file()
