"""Long commands a user can watch and stop: progress on stderr with or without a terminal,
Ctrl-C (SIGINT) and SIGTERM keeping every training seed's work, and the resume that continues
each seed from its checkpoint (dss14_env/core/progress.py, dss14_env/core/stop.py,
agents/train_control.py, agents/campaign.py, cli.py)."""

from __future__ import annotations

import io
import json
import os
import re
import shlex
import signal
from pathlib import Path

import pytest
import yaml

from dss14_env import cli
from dss14_env.core.progress import Progress, format_duration
from dss14_env.core.stop import Stopped, StopRequests, exit_status, terminate_as_interrupt

TINY = dict(algo="ppo", env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=512,
            seed=0, n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=256,
            eval_seeds=[7], checkpoint_freq=0, progress_bar=False, verbose=0)


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


# ------------------------------------------------------------------ progress
def test_lines_without_a_terminal_at_start_every_tenth_and_at_the_end() -> None:
    out, clock = io.StringIO(), _Clock()
    with Progress(100, "seed_0", unit="steps", stream=out, tty=False, clock=clock) as p:
        for _ in range(100):
            clock.t += 1.0
            p.update(1)
    lines = out.getvalue().splitlines()
    assert lines[0] == "seed_0: 0/100 steps (0 %), starting"
    assert lines[1] == "seed_0: 10/100 steps (10 %), 0:10 elapsed, ETA 1:30"
    assert len(lines) == 1 + 10 + 1  # the start, one per tenth, the end
    assert lines[-1] == "seed_0: 100/100 steps (100 %) done in 1:40"


def test_lines_also_every_interval_when_a_tenth_takes_long() -> None:
    out, clock = io.StringIO(), _Clock()
    p = Progress(1000, "bench", unit="episodes", stream=out, tty=False, clock=clock, every_s=30.0)
    clock.t = 31.0
    p.update(1)  # far from a tenth, but 30 s since the last line
    assert out.getvalue().splitlines()[-1] == "bench: 1/1000 episodes (0 %), 0:31 elapsed, ETA 8:36:09"


def test_a_resumed_count_starts_from_where_it_was_and_its_rate_leaves_that_out() -> None:
    out, clock = io.StringIO(), _Clock()
    p = Progress(100, "seed_1", unit="steps", initial=50, stream=out, tty=False, clock=clock)
    clock.t = 10.0
    p.update_to(60)
    first, second = out.getvalue().splitlines()
    assert first == "seed_1: 50/100 steps (50 %), continuing"
    assert second.endswith("0:10 elapsed, ETA 0:40")  # 10 steps in 10 s, 40 to go


def test_disabled_progress_writes_nothing() -> None:
    out = io.StringIO()
    with Progress(10, "x", stream=out, tty=False, enabled=False) as p:
        p.update(10)
    assert out.getvalue() == ""


def _read_all(fd: int) -> str:
    """Everything written to a terminal's other end so far (one read may return only a part)."""
    import select

    chunks = []
    while select.select([fd], [], [], 0.5)[0]:
        chunk = os.read(fd, 65536)
        if not chunk:
            break
        chunks.append(chunk)
    return b"".join(chunks).decode()


def test_a_terminal_gets_a_bar() -> None:
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns
    try:
        with os.fdopen(slave, "w", closefd=True) as stream:
            with Progress(50, "seed_0", unit="steps", stream=stream) as p:  # tty detected
                p.update(25)
            stream.flush()
            text = _read_all(master)
    finally:
        os.close(master)
    assert "seed_0" in text and "25/50" in text and "\r" in text and "starting" not in text


@pytest.mark.parametrize("s,text", [(0, "0:00"), (59.6, "1:00"), (61, "1:01"), (3725, "1:02:05")])
def test_durations_read_as_the_bar_writes_them(s: float, text: str) -> None:
    assert format_duration(s) == text


# ------------------------------------------------------------------ signals
def test_the_first_signal_is_recorded_and_the_second_stops_at_once() -> None:
    before = signal.getsignal(signal.SIGINT)
    with StopRequests() as req:
        signal.raise_signal(signal.SIGTERM)
        assert req.signum == signal.SIGTERM
        with pytest.raises(Stopped) as info:
            signal.raise_signal(signal.SIGINT)
    assert info.value.exit_status == 130
    assert signal.getsignal(signal.SIGINT) is before  # restored


def test_sigterm_raises_an_interruption_with_status_143() -> None:
    with pytest.raises(KeyboardInterrupt) as info, terminate_as_interrupt():
        signal.raise_signal(signal.SIGTERM)
    assert exit_status(info.value) == 143
    assert exit_status(KeyboardInterrupt()) == 130


def test_a_command_stopped_by_sigterm_says_so_and_exits_143(capsys) -> None:
    import argparse

    def work(args):
        signal.raise_signal(signal.SIGTERM)

    assert cli.run_command(argparse.Namespace(command="demo", func=work, argv=[])) == 143
    assert "dss14 demo: stopped (SIGTERM)" in capsys.readouterr().err


# ------------------------------------------------------------------ training
def _signal_at(monkeypatch, run_name: str, steps: int, sig: int) -> None:
    """Send ``sig`` to this process once the run ``run_name`` passes ``steps`` steps."""
    from stable_baselines3.common.callbacks import BaseCallback

    import dss14_env.agents.train as T

    real = T.progress_callback

    class Send(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= steps and not getattr(self, "sent", False):
                self.sent = True
                signal.raise_signal(sig)
            return True

    def watched(total, start, desc, enabled=True):
        from stable_baselines3.common.callbacks import CallbackList

        shown = real(total, start, desc, enabled)
        both = CallbackList([shown] + ([Send()] if desc == run_name else []))
        both.write = shown.write
        return both

    monkeypatch.setattr(T, "progress_callback", watched)


def test_a_training_run_prints_progress_lines_without_a_terminal(tmp_path: Path, capsys) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "eval_freq": 0, "total_timesteps": 256}))
    assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == f"ppo on Pendulum-v1: one run of 256 steps into {tmp_path / 'r'}"
    assert err[1] == "r: 0/256 steps (0 %), starting"
    assert any(line.startswith("r: ") and "elapsed, ETA" in line for line in err)
    assert err[-1].startswith("r: 256/256 steps (100 %) done in ")
    assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(tmp_path / "q"),
                     "--no-progress"]) == 0
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------ the first line
def _env_check_sees(monkeypatch, capsys, module: str) -> list[str]:
    """Replace ``module``'s environment check by one that records what stderr held when it was
    called, then refuses (so nothing is trained)."""
    import importlib

    seen: list[str] = []

    def check(cfg):
        seen.append(capsys.readouterr().err)
        raise ValueError("environment check reached")

    monkeypatch.setattr(importlib.import_module(module), "check_env", check)
    return seen


@pytest.mark.parametrize("module, config, options, header", [
    ("dss14_env.agents.campaign", {}, ["--train-seeds", "0-1"], "2 runs of 512 steps"),
    ("dss14_env.agents.sweep", {"sweep": {"env_kwargs.g": [9.0, 10.0]}}, ["--train-seeds", "0"],
     "2 runs of 512 steps"),
    ("dss14_env.agents.train", {}, [], "one run of 512 steps"),
], ids=["campaign", "sweep", "single-run"])
def test_training_says_its_first_line_before_the_environment_check(
        tmp_path: Path, monkeypatch, capsys, module: str, config: dict, options: list[str],
        header: str) -> None:
    """The check builds the model (seconds): the first line comes before it; a refused
    environment leaves no folder, and ``--no-progress`` keeps a single run silent."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, **config}))
    seen = _env_check_sees(monkeypatch, capsys, module)
    out = tmp_path / "out"
    argv = ["train", "ppo", "--config", str(cfg), *options, "--out", str(out)]
    assert cli.main(argv) == 2
    assert seen == [f"ppo on Pendulum-v1: {header} into {out}\n"]
    assert "environment check reached" in capsys.readouterr().err
    assert not out.exists()
    if not options:
        assert cli.main([*argv, "--no-progress"]) == 2 and seen[1] == ""


def test_a_refused_campaign_folder_is_said_at_once_without_a_first_line(tmp_path: Path, monkeypatch,
                                                                         capsys) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(TINY))
    seen = _env_check_sees(monkeypatch, capsys, "dss14_env.agents.campaign")
    out = tmp_path / "camp"
    out.mkdir()
    (out / "summary.json").write_text("{}")  # the user's file where the campaign writes
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert seen == [] and err.count("\n") == 1 and "summary.json" in err, err
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out",
                     str(tmp_path / "none"), "--resume"]) == 2
    err = capsys.readouterr().err
    assert seen == [] and err.count("\n") == 1 and "no campaign to continue" in err, err


@pytest.mark.parametrize("sig,stop_in", [(signal.SIGINT, "seed_1"), (signal.SIGTERM, "seed_0")])
def test_a_stopped_campaign_keeps_every_seeds_work_and_resume_continues_each(
        tmp_path: Path, monkeypatch, capsys, sig: int, stop_in: str) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(TINY))
    out = tmp_path / "camp"
    _signal_at(monkeypatch, stop_in, 300, sig)
    argv = ["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out", str(out)]
    assert cli.main(argv) == 128 + sig
    err = capsys.readouterr().err.splitlines()
    stopped = json.loads((out / stop_in / "checkpoints").iterdir().__next__().joinpath(
        "counters.json").read_text())["num_timesteps"]
    assert 300 <= stopped < 512  # the checkpoint is where it stopped (checkpoint_freq is 0)
    assert f"{signal.Signals(sig).name}: stopping at " in "\n".join(err)  # said as it stops
    last = err[-1]
    assert f"campaign stopped ({signal.Signals(sig).name})" in last
    want = {"seed_1": f"seed_0 finished, seed_1 at {stopped} steps (checkpoints/{stopped}_steps)",
            "seed_0": f"seed_0 at {stopped} steps (checkpoints/{stopped}_steps), seed_1 nothing yet"}
    assert want[stop_in] in last
    command = shlex.split(last.split("continue with: ")[1])
    assert command[:2] == ["dss14", "train"] and command[-1] == "--resume"
    finished_before = {}
    if stop_in == "seed_1":
        finished_before = json.loads((out / "seed_0" / "train_summary.json").read_text())

    monkeypatch.undo()
    assert cli.main(command[1:]) == 0
    err = capsys.readouterr().err
    assert f"{stop_in}: continuing from checkpoints/{stopped}_steps to 512 steps" in err
    for k in (0, 1):
        summary = json.loads((out / f"seed_{k}" / "train_summary.json").read_text())
        assert summary["num_timesteps"] >= 512
        if f"seed_{k}" == stop_in:  # its step counter continues from the checkpoint
            assert summary["start_timesteps"] == stopped
            assert summary["resumed_from"].endswith(f"{stopped}_steps")
    if finished_before:  # the finished seed is scored again, not retrained
        assert json.loads((out / "seed_0" / "train_summary.json").read_text()) == finished_before
    assert json.loads((out / "summary.json").read_text())["seed_indices"] == [0, 1]


@pytest.mark.slow
def test_a_stopped_campaign_on_ray_keeps_a_checkpoint_of_every_running_seed(tmp_path: Path, capsys) -> None:
    """Ctrl-C while two seeds train at once as Ray tasks: each saves a checkpoint where it stops
    (the executor stops its tasks as Ctrl-C would), and the resume continues both from there."""
    import threading
    import time

    pytest.importorskip("ray")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "total_timesteps": 20_000, "eval_freq": 0}))
    out = tmp_path / "camp"

    def interrupt_once_both_train() -> None:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            if all((out / f"seed_{k}" / "config.yaml").is_file() for k in (0, 1)):  # both built
                time.sleep(1.0)
                signal.raise_signal(signal.SIGINT)
                return
            time.sleep(0.2)

    threading.Thread(target=interrupt_once_both_train, daemon=True).start()
    argv = ["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out", str(out),
            "--num-cpus", "2"]
    assert cli.main(argv) == 130
    last = capsys.readouterr().err.strip().splitlines()[-1]
    stopped = {}
    for k in (0, 1):
        (ckpt,) = (out / f"seed_{k}" / "checkpoints").iterdir()
        stopped[k] = int(ckpt.name[:-6])
        assert 0 < stopped[k] < 20_000
        assert f"seed_{k} at {stopped[k]} steps" in last
    command = shlex.split(last.split("continue with: ")[1])
    assert command[-3:] == ["--num-cpus", "2"] or "--num-cpus" in command
    assert cli.main(command[1:]) == 0
    for k in (0, 1):
        summary = json.loads((out / f"seed_{k}" / "train_summary.json").read_text())
        assert summary["start_timesteps"] == stopped[k] and summary["num_timesteps"] >= 20_000


@pytest.mark.slow
def test_subprocess_workers_ignore_ctrl_c_so_that_only_the_main_process_stops() -> None:
    """A terminal's Ctrl-C reaches every process of the foreground group, the workers of a
    ``vec_env: subproc`` training included: they go on answering, and close when told.  (A
    worker imports stable-baselines3 and torch as it starts: 5-20 s.)"""
    import functools

    import gymnasium as gym

    from dss14_env.agents.vec_env import make_subproc_vec_env

    venv = make_subproc_vec_env([functools.partial(gym.make, "Pendulum-v1")])  # one worker: seconds
    try:
        for p in venv.processes:
            os.kill(p.pid, signal.SIGINT)
        obs = venv.reset()
        assert obs.shape == (1, 3) and all(p.is_alive() for p in venv.processes)
    finally:
        venv.close()
    assert [p.exitcode for p in venv.processes] == [0]


@pytest.mark.slow
@pytest.mark.parametrize("vec_env", ["dummy", "subproc"])
def test_a_terminal_session_shows_a_bar_and_ctrl_c_to_its_process_group_keeps_a_checkpoint(
        tmp_path: Path, vec_env: str) -> None:
    """``dss14 train`` on a pseudo-terminal, stopped as a terminal's Ctrl-C stops it (SIGINT to
    the whole foreground process group, subprocess workers included)."""
    import fcntl
    import pty
    import select
    import struct
    import subprocess
    import sys
    import termios
    import time

    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "total_timesteps": 1_000_000, "eval_freq": 0,
                                   "vec_env": vec_env}))
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "dss14_env.cli", "train", "ppo", "--config", str(cfg),
                             "--out", str(tmp_path / "r")], stdin=slave, stdout=slave, stderr=slave,
                            start_new_session=True)
    os.close(slave)
    text, sent, deadline = b"", False, time.monotonic() + 300
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.5)
            chunk = b""
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # the terminal's other end closed: the command ended
                    break
                text += chunk
            if not sent and re.search(rb"r: +\d+%\|.*steps?/s", text):
                os.killpg(proc.pid, signal.SIGINT)
                sent = True
            if proc.poll() is not None and not chunk:
                break
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
    assert sent, text.decode(errors="replace")[-2000:]
    assert proc.wait() == 130
    (ckpt,) = (tmp_path / "r" / "checkpoints").iterdir()
    lines = text.decode(errors="replace").replace("\r", "\n")
    assert f"kept checkpoint {ckpt}" in " ".join(lines.split())
    assert "Traceback" not in lines and "Error" not in lines, lines[-3000:]


@pytest.mark.slow
def test_sigterm_to_the_process_group_of_a_subprocess_training_keeps_a_checkpoint(tmp_path: Path) -> None:
    """A SIGTERM to the whole process group (a service manager's stop) ends the subprocess
    workers too: the main process keeps a checkpoint where it stopped and says so in one line."""
    import subprocess
    import sys
    import time

    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "total_timesteps": 1_000_000, "eval_freq": 0,
                                   "vec_env": "subproc"}))
    log = tmp_path / "stderr.txt"
    with log.open("w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "dss14_env.cli", "train", "ppo", "--config", str(cfg),
                                 "--out", str(tmp_path / "r")], stdout=err, stderr=err,
                                start_new_session=True)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and "r: 0/1000000 steps (0 %), starting" not in log.read_text():
            time.sleep(0.5)
        time.sleep(2.0)  # into the training
        os.killpg(proc.pid, signal.SIGTERM)
        assert proc.wait(timeout=300) == 143
    text = log.read_text()
    (ckpt,) = (tmp_path / "r" / "checkpoints").iterdir()
    assert f"training stopped (SIGTERM) at {ckpt.name[:-6]} steps; kept checkpoint {ckpt}" in text, text
    assert "Traceback" not in text and "Error" not in text, text


def test_a_stop_as_a_seed_ends_keeps_it_whole_and_still_stops_the_campaign(tmp_path: Path, monkeypatch,
                                                                             capsys) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "eval_freq": 0}))
    out = tmp_path / "camp"
    _signal_at(monkeypatch, "seed_0", 512, signal.SIGINT)  # at its last step
    argv = ["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out", str(out)]
    assert cli.main(argv) == 130
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "kept in" in last and "seed_0 finished, seed_1 nothing yet" in last
    assert not (out / "seed_1").exists()


@pytest.mark.parametrize("at,eval_freq", [(256, 256), (128, 4096)])
def test_a_stop_skips_the_validation_it_would_start_and_the_final_one(
        tmp_path: Path, monkeypatch, at: int, eval_freq: int) -> None:
    """A stop asked for as a validation round is due (256, every 256 steps), or before a run
    that would be validated at its end (every 4096 steps, a 512-step run), is not followed by
    that validation: the run stops with its checkpoint and records no evaluation.
    """
    from dss14_env.agents.train import TrainingInterrupted, train

    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**TINY, "eval_freq": eval_freq}))
    _signal_at(monkeypatch, "r", at, signal.SIGTERM)
    with pytest.raises(TrainingInterrupted) as info:
        train(cfg, run_dir=tmp_path / "r", progress=False)
    assert info.value.steps >= at
    assert not (tmp_path / "r" / "eval" / "evaluations.npz").exists()
    assert not (tmp_path / "r" / "eval" / "best").exists()
    assert list((tmp_path / "r" / "checkpoints").iterdir())
