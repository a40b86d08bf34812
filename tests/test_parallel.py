"""The executors of dss14_env.core.parallel: in-process and on a local Ray (num_cpus=2), the
same numbers either way, pinned threads, failures named, Ray optional with an install hint."""

from __future__ import annotations

import json
import os
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
import yaml
from threadpoolctl import threadpool_info

from dss14_env.core import parallel as P


# ------------------------------------------------------------------ work items (module level:
# Ray ships them to its workers by value, see the fixture)
def blas_item(seed: int) -> dict:
    """A BLAS-heavy computation whose last bits depend on the summation order."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((300, 300))
    x = np.linalg.solve(a @ a.T + 300 * np.eye(300), rng.standard_normal(300))
    return {"seed": seed, "x": x.tolist()}


def trial(seed: int) -> dict:
    """A stand-in training trial: a small torch network fitted for 60 steps from ``seed``;
    returns its final loss and a checksum of its weights (floats, bit for bit)."""
    import torch

    torch.manual_seed(seed)
    x = torch.linspace(-2, 2, 256).unsqueeze(1)
    y = torch.sin(3 * x) + 0.1 * torch.randn_like(x)
    net = torch.nn.Sequential(torch.nn.Linear(1, 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, 1))
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    for _ in range(60):
        opt.zero_grad()
        loss = torch.mean((net(x) - y) ** 2)
        loss.backward()
        opt.step()
    w = torch.cat([p.detach().flatten() for p in net.parameters()])
    return {"seed": seed, "loss": float(loss.detach()), "weights_sum": float(w.double().sum()),
            "threads": torch.get_num_threads()}


def where(item: int) -> dict:
    return {"pid": os.getpid(), "env": {v: os.environ.get(v) for v in P.THREAD_ENV_VARS},
            "blas_threads": sorted({d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"})}


def fails_on_three(item: int) -> int:
    if item == 3:
        raise ValueError("three is bad")
    return item


# ------------------------------------------------------------------ in-process
def test_serial_returns_every_item_in_order() -> None:
    with P.SerialExecutor() as ex:
        assert list(ex.map_unordered(lambda v: v * v, [3, 1, 2])) == [(0, 9), (1, 1), (2, 4)]
        assert ex.n_workers == 1 and ex.describe()["kind"] == "serial"


def test_serial_failure_names_the_item() -> None:
    ex = P.SerialExecutor()
    got = []
    with pytest.raises(P.TaskFailedError, match=r"^chunk 3 failed: ValueError: three is bad$"):
        for _, r in ex.map_unordered(fails_on_three, range(6), labels=[f"chunk {i}" for i in range(6)]):
            got.append(r)
    assert got == [0, 1, 2]  # what finished before stays valid


def test_pinned_threads_limits_blas_and_restores() -> None:
    import scipy.linalg  # noqa: F401  (entering loads numpy's and scipy's BLAS: compare like with like)

    before = sorted(d["num_threads"] for d in threadpool_info())
    with P.pinned_threads(1):
        assert {d["num_threads"] for d in threadpool_info()} == {1}
    assert sorted(d["num_threads"] for d in threadpool_info()) == before


def test_pinned_threads_sets_torch_and_restores() -> None:
    import torch

    before = torch.get_num_threads()
    with P.pinned_threads(1, torch=True):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before


@pytest.mark.parametrize("make,message", [
    (lambda: P.SerialExecutor(threads=0), "threads: must be an integer >= 1"),
    (lambda: P.pinned_threads(1.5), "threads: must be an integer >= 1"),
    (lambda: P.RayExecutor(num_cpus=0), "--num-cpus: must be an integer >= 1"),
    (lambda: P.RayExecutor(address="auto", num_cpus=2), "--num-cpus: sizes a local Ray"),
    (lambda: P.RayExecutor(address=" "), "--address: must be 'auto' or a Ray cluster address"),
    (lambda: P.RayExecutor(cpus_per_task=0), "cpus_per_task: must be an integer >= 1"),
])
def test_bad_options_are_named_before_ray_starts(make, message, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # nothing may reach Ray
    with pytest.raises(ValueError, match=message):
        make()


def test_without_ray_the_error_says_how_to_install_it(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    with pytest.raises(P.RayNotInstalledError, match=r'pip install -e "\.\[ray\]"'):
        P.make_executor(ray=True)
    assert isinstance(P.make_executor(), P.SerialExecutor)  # in-process needs no Ray


# ------------------------------------------------------------------ on a local Ray
@pytest.fixture(autouse=True)
def by_value(request):
    """This module's functions go to the Ray workers by value (they cannot import a test module)."""
    if "local_ray" not in request.fixturenames:
        yield
        return
    ray = request.getfixturevalue("local_ray")
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    yield
    ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


def test_ray_gives_the_same_numbers_as_in_process(local_ray) -> None:
    seeds = [0, 1, 2, 3]
    serial = dict(P.SerialExecutor().map_unordered(blas_item, seeds))
    with P.RayExecutor() as ex:
        assert ex.n_workers == 2
        on_ray = dict(ex.map_unordered(blas_item, seeds))
    assert on_ray == serial  # bit for bit
    assert local_ray.is_initialized()  # a running Ray is left running


def test_training_trials_same_seed_same_result_either_way(local_ray) -> None:
    """Stand-in for the per-seed training trials: torch, seeded, pinned to one thread."""
    seeds = [0, 1, 2]
    serial = dict(P.SerialExecutor(torch=True).map_unordered(trial, seeds))
    on_ray = dict(P.RayExecutor(torch=True).map_unordered(trial, seeds))
    assert on_ray == serial
    assert {r["threads"] for r in on_ray.values()} == {1}
    assert len({r["loss"] for r in serial.values()}) == 3  # the seeds do differ


def test_ray_tasks_are_pinned_and_spread(local_ray) -> None:
    res = dict(P.RayExecutor().map_unordered(where, range(8)))
    assert all(r["env"] == {v: "1" for v in P.THREAD_ENV_VARS} for r in res.values())
    assert all(r["blas_threads"] == [1] for r in res.values())
    assert len({r["pid"] for r in res.values()}) >= 2 and os.getpid() not in {r["pid"] for r in res.values()}


def test_ray_failure_names_the_item(local_ray) -> None:
    with pytest.raises(P.TaskFailedError, match=r"^seed 3 failed: ValueError: three is bad$"):
        list(P.RayExecutor().map_unordered(fails_on_three, range(6), labels=[f"seed {i}" for i in range(6)]))


# ------------------------------------------------------------------ the cluster recipe
def test_cluster_recipe_is_a_valid_ray_cluster_config() -> None:
    """docs/cluster.yaml passes Ray's own cluster-config schema and installs this version."""
    ray = pytest.importorskip("ray")
    jsonschema = pytest.importorskip("jsonschema")
    root = Path(__file__).resolve().parents[1]
    schema = json.loads((Path(ray.__file__).parent / "autoscaler" / "ray-schema.json").read_text())
    cfg = yaml.safe_load((root / "docs" / "cluster.yaml").read_text())
    jsonschema.validate(cfg, schema)
    version = metadata.version("dss14-env")
    wheel = f"dss14_env-{version}-py3-none-any.whl"
    assert cfg["file_mounts"] == {f"/tmp/{wheel}": f"dist/{wheel}"}
    setup = "\n".join(cfg["setup_commands"])
    assert "torch==2.13.0" in setup and f'"/tmp/{wheel}[ray]"' in setup
    assert cfg["provider"]["type"] == "local" and len(cfg["provider"]["worker_ips"]) == cfg["max_workers"]


# ------------------------------------------------------------------ dss14 train --seeds --ray
#: a training run of a few seconds (Pendulum: no DSS14 model to build in the workers)
TINY_TRAINING = dict(algo="ppo", env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=128,
                     seed=0, n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=64,
                     eval_seeds=[7], checkpoint_freq=0, progress_bar=False, verbose=0)


def _seed_results(folder: Path) -> dict:
    s = json.loads((folder / "summary.json").read_text())
    for e in s["per_seed"]:
        e.pop("wall_s")
    return {k: s[k] for k in ("per_seed", "aggregate", "training_seeds")}


def test_train_seeds_on_ray_same_numbers_as_in_process(local_ray, tmp_path) -> None:
    """``dss14 train ppo --seeds 0-2 --ray``: three runs as Ray tasks give the summary (every
    seed's test returns, the IQM and its interval) of the same runs one after another."""
    from dss14_env import cli
    from dss14_env.agents.campaign import train_seeds

    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(TINY_TRAINING))
    serial = train_seeds(str(cfg), [0, 1, 2], tmp_path / "serial", figures=False)
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0-2", "--ray",
                     "--out", str(tmp_path / "ray")]) == 0
    on_ray = _seed_results(tmp_path / "ray")
    assert on_ray == _seed_results(serial)
    assert [e["seed_index"] for e in on_ray["per_seed"]] == [0, 1, 2]
    assert len({e["final"]["eval"]["mean_return"] for e in on_ray["per_seed"]}) == 3


def test_train_sweep_on_ray_same_numbers_as_in_process(local_ray, tmp_path) -> None:
    """``dss14 train ppo --train-seeds 0-1 --ray`` with a 2-point sweep: the four (point, seed) runs as
    Ray tasks give the sweep.json and the per-point summaries of the same sweep in-process."""
    from dss14_env import cli
    from dss14_env.agents.sweep import train_sweep

    cfg = tmp_path / "sweep.yaml"
    cfg.write_text(yaml.safe_dump({**TINY_TRAINING, "sweep": {"learning_rate": [3e-4, 1e-2]}}))
    serial = train_sweep(str(cfg), [0, 1], tmp_path / "serial", figures=False)
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--ray",
                     "--out", str(tmp_path / "ray")]) == 0
    report = json.loads((tmp_path / "ray" / "sweep.json").read_text())
    assert report == json.loads((serial / "sweep.json").read_text())
    assert [p["label"] for p in report["points"]] == ["learning_rate=0.0003", "learning_rate=0.01"]
    for p in report["points"]:
        assert _seed_results(tmp_path / "ray" / p["folder"]) == _seed_results(serial / p["folder"])
    finals = {v for p in report["points"] for v in p["aggregate"]["final"]["eval"]["per_seed"]}
    assert len(finals) == 4  # four different runs


@pytest.mark.parametrize("extra,message", [
    (["--ray"], "--ray runs the runs of --train-seeds as Ray tasks: give --train-seeds and --out"),
    (["--train-seeds", "0-1", "--out", "x", "--address", "auto", "--num-cpus", "2"],
     "--num-cpus: sizes a local Ray"),
])
def test_train_bad_ray_options_are_one_line(extra, message, tmp_path, capsys, monkeypatch) -> None:
    from dss14_env import cli

    monkeypatch.chdir(tmp_path)
    assert cli.main(["train", "ppo", "--config", "ppo_smoke"] + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("dss14 train: error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_train_without_ray_says_how_to_install_it(tmp_path, capsys, monkeypatch) -> None:
    from dss14_env import cli

    monkeypatch.setitem(sys.modules, "ray", None)
    assert cli.main(["train", "ppo", "--config", "ppo_smoke", "--train-seeds", "0-4", "--ray",
                     "--out", str(tmp_path / "x")]) == 2
    assert 'pip install -e ".[ray]"' in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
