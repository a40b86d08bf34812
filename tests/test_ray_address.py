"""Every way of addressing a Ray cluster is checked before any work: ``--address``, the
``RAY_ADDRESS`` environment variable (which ``ray.init`` reads when given no address) and the
cluster ``ray start`` recorded on this machine.  A cluster nobody answers is one line naming the
address and what named it, at once, never a hang.
"""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from dss14_env import cli
from dss14_env.core.parallel import (
    RAY_CLUSTER_FILE,
    check_ray_options,
    probe_address,
    ray_preflight,
    ray_target,
)


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def no_cluster(monkeypatch, tmp_path: Path) -> Path:
    """No address in the environment and an empty Ray temporary folder: Ray would start locally."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path / "raytmp"))
    return tmp_path / "raytmp" / "ray"


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def test_the_target_follows_rays_order(no_cluster: Path, monkeypatch) -> None:
    assert ray_target(None).address is None and ray_target(None).describe() == "Ray (local)"
    assert ray_target("10.0.0.1:6380").address == "10.0.0.1:6380"
    no_cluster.mkdir(parents=True)
    (no_cluster / RAY_CLUSTER_FILE).write_text("10.0.0.2:6379\n")
    assert ray_target(None).address == "10.0.0.2:6379" and ray_target("auto").address == "10.0.0.2:6379"
    monkeypatch.setenv("RAY_ADDRESS", "10.0.0.3:6379")
    assert ray_target(None).address == "10.0.0.3:6379" and ray_target("auto").address == "10.0.0.3:6379"
    assert ray_target("10.0.0.1:6380").address == "10.0.0.1:6380"  # an explicit address wins
    assert "RAY_ADDRESS" in ray_target(None).describe()


def test_an_unreachable_ray_address_variable_is_one_line(no_cluster: Path, monkeypatch) -> None:
    address = f"127.0.0.1:{_closed_port()}"
    monkeypatch.setenv("RAY_ADDRESS", address)
    for given in (None, "auto"):
        with pytest.raises(RuntimeError, match=rf"^RAY_ADDRESS={address} \(environment variable\): "
                                               rf"no Ray cluster can be reached"):
            probe_address(given)


def test_an_unreachable_recorded_cluster_is_one_line(no_cluster: Path) -> None:
    address = f"127.0.0.1:{_closed_port()}"
    no_cluster.mkdir(parents=True)
    (no_cluster / RAY_CLUSTER_FILE).write_text(address)
    with pytest.raises(RuntimeError, match=rf"recorded in .*{RAY_CLUSTER_FILE} by ray start .*"
                                           rf"no Ray cluster can be reached at {address}"):
        probe_address(None)


def test_a_bad_ray_address_variable_is_named(no_cluster: Path, monkeypatch) -> None:
    monkeypatch.setenv("RAY_ADDRESS", "head:port")
    with pytest.raises(ValueError, match=r"^RAY_ADDRESS: must be 'auto', host:port"):
        check_ray_options(None)


def test_num_cpus_is_bounded_and_only_for_a_local_ray(no_cluster: Path, monkeypatch) -> None:
    with pytest.raises(ValueError, match=r"^--num-cpus: must be an integer >= 1 and <= \d+"):
        check_ray_options(None, 100_000)
    monkeypatch.setenv("RAY_ADDRESS", "10.0.0.3:6379")
    with pytest.raises(ValueError, match=r"^--num-cpus: sizes a local Ray; RAY_ADDRESS=10.0.0.3:6379"):
        check_ray_options(None, 4)


@pytest.mark.parametrize("command", ["campaign", "train"])
def test_commands_refuse_an_unreachable_ray_address_variable_before_work(
        no_cluster: Path, monkeypatch, tmp_path: Path, capsys, command: str) -> None:
    pytest.importorskip("ray")
    address = f"127.0.0.1:{_closed_port()}"
    monkeypatch.setenv("RAY_ADDRESS", address)
    out = tmp_path / "out"
    argv = (["campaign", "--plants", "2", "--steps", "300", "--controllers", "pi_kp1"]
            if command == "campaign" else ["train", "ppo", "--config", "ppo_smoke", "--seeds", "0"])
    assert cli.main([*argv, "--ray", "--out", str(out)]) == 2
    _one_line(capsys, f"RAY_ADDRESS={address}", "no Ray cluster can be reached")
    assert not out.exists()


def test_preflight_names_the_local_ray(no_cluster: Path) -> None:
    pytest.importorskip("ray")
    assert ray_preflight(None).describe() == "Ray (local)"
