"""What a user types and where the output goes: a policy folder named like a shipped one, a
direction given twice, a report read by ``head`` or an ASCII terminal, a bad ``--out`` with
policies to load, a configuration of the wrong kind.
"""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import pytest

from dss14_env import cli
from dss14_env.agents.policy import shipped_policy
from dss14_env.bench import catalog
from dss14_env.bench.campaign_spec import CampaignOptionError, CampaignSpec
from dss14_env.bench.plan import BenchOptionError, build_plan
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.schema import ConfigError


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


# ------------------------------------------------------------------ a policy named like a shipped one
def test_a_local_folder_named_like_a_shipped_policy_is_never_the_shipped_one(tmp_path, monkeypatch,
                                                                             capsys) -> None:
    monkeypatch.chdir(tmp_path)
    shutil.copytree(shipped_policy("ppo_residual_lqg"), tmp_path / "ppo_plain")  # the user's training
    out = str(tmp_path / "o")
    assert cli.main(["bench", "--controllers", "ppo", "--ppo-model", "ppo_plain", "--quick",
                     "--out", out]) == 2
    _one_line(capsys, "--ppo-model", "'ppo_plain'", "rename the folder", "--controllers ppo_plain")
    with pytest.raises(CampaignOptionError, match="--ppo-model: .*'ppo_plain'.*rename the folder"):
        CampaignSpec(controllers=("ppo",), ppo_model="ppo_plain")
    assert not (tmp_path / "o").exists()


def test_a_policy_path_is_a_path_and_scores_under_its_folders_name(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert catalog.policy_row("ppo_plain").policy_path() == Path("ppo_plain")  # never the shipped one
    with pytest.raises(BenchOptionError, match="--ppo-model"):  # no such folder here
        build_plan(controllers=["ppo"], ppo_model="residual_pi", quick=True, out=tmp_path / "o")
    shutil.copytree(shipped_policy("ppo_plain"), tmp_path / "mine")
    plan = build_plan(controllers=["ppo"], ppo_model="mine", quick=True, out=tmp_path / "o")
    assert plan.controllers == ["mine"] and plan.rows[0].policy_path() == Path("mine")
    assert catalog.CONTROLLERS["ppo_plain"].policy_path() == shipped_policy("ppo_plain")


# ------------------------------------------------------------------ one direction given twice
@pytest.mark.parametrize("directions", [["front", "0"], ["side", "90"], ["45", "45.0"]])
def test_a_direction_given_twice_is_refused(directions, tmp_path, capsys) -> None:
    assert cli.main(["campaign", "--controllers", "pi_kp1", "--directions", *directions,
                     "--out", str(tmp_path / "c")]) == 2
    _one_line(capsys, "--directions: a direction is repeated")


# ------------------------------------------------------------------ the report's reader
@pytest.fixture
def fake_reproduce(monkeypatch) -> None:
    """``dss14 reproduce`` whose work is a few files and a report with a Greek letter."""
    from dss14_env import reproduce as R

    def fake(out, model, figures=True):
        atomic_write_text(Path(out, "metrics.json"), "{}")
        atomic_write_text(Path(out, "metrics.md"), "")
        return {"markdown": "| 3σ (mdeg) | 1.0 |\n" * 200, "figures": [], "failed": [], "metrics": {}}

    monkeypatch.setattr(R, "reproduce", fake)
    monkeypatch.setattr("dss14_env.model.assembly.default_model", lambda: None)


class _ClosedPipe(io.TextIOBase):
    """A standard output whose reader went away after ``n`` writes (``| head``)."""

    def __init__(self, n: int) -> None:
        self.n = n

    def write(self, s: str) -> int:
        self.n -= 1
        if self.n < 0:
            raise BrokenPipeError(32, "Broken pipe")
        return len(s)


@pytest.mark.parametrize("stdout", [lambda: _ClosedPipe(1),
                                    lambda: io.TextIOWrapper(io.BytesIO(), encoding="ascii")])
def test_a_finished_run_exits_0_whoever_reads_its_report(stdout, fake_reproduce, tmp_path,
                                                          monkeypatch, capsys) -> None:
    out = tmp_path / "rp"
    monkeypatch.setattr("sys.stdout", stdout())
    assert cli.main(["reproduce", "--out", str(out), "--no-figures"]) == 0
    assert capsys.readouterr().err == "" and (out / "metrics.json").is_file()


def test_an_ascii_report_escapes_what_it_cannot_show(fake_reproduce, tmp_path, monkeypatch) -> None:
    buf = io.BytesIO()
    monkeypatch.setattr("sys.stdout", io.TextIOWrapper(buf, encoding="ascii"))
    assert cli.main(["reproduce", "--out", str(tmp_path / "rp"), "--no-figures"]) == 0
    import sys

    sys.stdout.flush()
    assert b"| 3\\u03c3 (mdeg) | 1.0 |" in buf.getvalue()


# ------------------------------------------------------------------ the folder before the policies
@pytest.mark.parametrize("command", [["bench", "--quick"], ["campaign", "--controllers", "pi_kp1", "ppo"]])
def test_a_bad_out_is_refused_before_any_policy_loads(command, tmp_path, monkeypatch, capsys) -> None:
    import dss14_env.agents.policy as P

    loaded: list = []
    monkeypatch.setattr(P, "load_policy", lambda *a, **k: loaded.append(a) or (_ for _ in ()).throw(
        RuntimeError("a policy was loaded")))
    f = tmp_path / "a_file"
    f.write_text("x")
    assert cli.main(command + ["--out", str(f)]) == 2
    _one_line(capsys, f"--out {f}: is a file")
    assert not loaded


# ------------------------------------------------------------------ a configuration of the wrong kind
@pytest.mark.parametrize("argv,given,wanted", [
    (["train", "ppo", "--config", "model"], "a model", "a training"),
    (["train", "ppo", "--config", "controllers"], "a controllers", "a training"),
    (["reproduce", "--config", "ppo"], "a training", "a model"),
    (["reproduce", "--config", "env"], "an environment", "a model"),
    (["reproduce", "--config", "wind"], "a wind", "a model"),
])
def test_a_configuration_of_the_wrong_kind_gets_one_message(argv, given, wanted, tmp_path,
                                                            capsys) -> None:
    out = tmp_path / "o"
    assert cli.main(argv + ["--out", str(out)]) == 2
    _one_line(capsys, f"{argv[-1]}.yaml: is {given} configuration", f"not {wanted} configuration")
    assert not out.exists()


def test_every_loader_names_the_kind_it_was_given() -> None:
    from dss14_env.agents.config import load_config
    from dss14_env.baselines.design import load_controllers_config
    from dss14_env.envs.config import load_env_config
    from dss14_env.model.config import load_model_config
    from dss14_env.wind.loads import load_wind_config

    for load, other in ((load_model_config, "wind"), (load_wind_config, "model"),
                        (load_controllers_config, "ppo"), (load_config, "env"),
                        (load_env_config, "controllers")):
        with pytest.raises(ConfigError, match=rf"{other}.yaml: is an? \w+ configuration .*, not an? "):
            load(other)
