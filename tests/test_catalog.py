"""The one catalog: every list of controllers and scenarios derives from its rows, and a new
controller or scenario is its module (or preset) plus its row."""

from __future__ import annotations

import dataclasses
import importlib
from types import MappingProxyType

import pytest

from dss14_env import cli
from dss14_env.agents import evaluation
from dss14_env.bench import bench as B
from dss14_env.bench import campaign as C
from dss14_env.bench import catalog, run
from dss14_env.bench import figures as F
from dss14_env.bench import plan as P
from dss14_env.envs import presets
from dss14_env.envs.presets import PRESETS, Preset


@pytest.mark.parametrize("row", [r for r in catalog.CONTROLLER_ROWS if r.policy is None],
                         ids=lambda r: r.name)
def test_a_rows_batchable_flag_is_its_classes(row) -> None:
    cls = getattr(importlib.import_module(row.module), row.cls)
    assert row.batchable == bool(getattr(cls, "batchable", False))


def test_policy_rows_name_shipped_policies_that_load() -> None:
    for row in catalog.CONTROLLER_ROWS:
        if row.policy is not None:
            assert row.batchable and row.policy_problem() is None, row.name


def test_every_list_derives_from_the_rows() -> None:
    names = [r.name for r in catalog.CONTROLLER_ROWS]
    scens = [r.name for r in catalog.SCENARIO_ROWS]
    assert len(set(names)) == len(names) and len(set(scens)) == len(scens)
    assert P.DEFAULT_CONTROLLERS == tuple(r.name for r in catalog.CONTROLLER_ROWS if r.bench)
    assert C.DEFAULT_CONTROLLERS == tuple(r.name for r in catalog.CONTROLLER_ROWS if r.campaign)
    assert C.known_controllers() == tuple(names)
    assert P.DEFAULT_SCENARIOS == tuple(scens)
    assert dict(P.DEFAULT_BUDGETS) == {r.name: r.default for r in catalog.SCENARIO_ROWS}
    assert dict(P.QUICK_BUDGETS) == {r.name: r.quick for r in catalog.SCENARIO_ROWS}
    assert sorted(F.WIND_SCENARIOS + F.MOVE_SCENARIOS) == sorted(scens)
    assert run.TRACED == tuple(r.name for r in catalog.SCENARIO_ROWS if r.traced)
    assert {r.name: r.loaded_axes for r in catalog.SCENARIO_ROWS if r.loaded_axes} == dict(P.LOADED_AXES)
    assert {d: s for d, (s, _) in P.SWEEP_DIRECTIONS.items()} == \
        {r.sweep: r.name for r in catalog.SCENARIO_ROWS if r.sweep}
    # the agents' evaluation tasks: the presets with one loaded axis, scored on it
    assert [(t.name, t.axis) for t in evaluation.DSS14_TASKS] == [("hold_front", "el"), ("hold_side", "az")]
    assert all(t.warmup_steps == round(PRESETS[t.name].warmup_s / 0.02) for t in evaluation.DSS14_TASKS)


def _help(capsys, command: str) -> str:
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("policy,name", [
    ("runs/a/eval/best", "a/best"), ("runs/a/checkpoints/step_100", "a/step_100"),
    ("runs/a", "a"), ("policy.zip", "policy")])
def test_a_trained_policy_scores_under_its_own_name(policy, name) -> None:
    row = catalog.policy_row(policy)
    assert row.name == name and row.policy == policy and row.batchable


def test_a_new_controller_and_scenario_are_their_module_and_their_row(monkeypatch, capsys,
                                                                      tmp_path) -> None:
    """The worked example of docs/bench.md: a controller row (its class exists: the PI) and a
    scenario preset with its row reach the plan, the runner, the help and the docs tables."""
    ctrl = catalog.ControllerRow("pi_still", "dss14_env.baselines.pi", "PIController",
                                 "kp 0.7 PI", args=("kp0.7",))
    scen = catalog.ScenarioRow("hold_side_70", catalog.Budget(4.0, 2, 1), catalog.Budget(2.0, 2, 1))
    preset = Preset("DSS14-HoldSide70-v0", {"scenario": "hold", "wind_speed_kmh": 70.0,
                                            "wind_direction": "side"}, 3000, 1.0,
                    "hold, 70 km/h side wind", "strong side wind", ("az",))
    monkeypatch.setattr(catalog, "CONTROLLER_ROWS", (*catalog.CONTROLLER_ROWS, ctrl))
    monkeypatch.setattr(catalog, "CONTROLLERS", {**catalog.CONTROLLERS, "pi_still": ctrl})
    monkeypatch.setattr(catalog, "SCENARIO_ROWS", (*catalog.SCENARIO_ROWS, scen))
    monkeypatch.setattr(catalog, "SCENARIOS", {**catalog.SCENARIOS, "hold_side_70": scen})
    monkeypatch.setattr(presets, "PRESETS", MappingProxyType({**PRESETS, "hold_side_70": preset}))
    monkeypatch.setattr(catalog, "PRESETS", presets.PRESETS)
    for command in ("bench", "campaign"):
        assert "pi_still" in _help(capsys, command)
    assert "hold_side_70" in _help(capsys, "bench")
    assert "`pi_still`" in catalog.controllers_table() and "`hold_side_70`" in catalog.scenarios_table()
    assert "pi_still" in P.build_plan().controllers
    plan = P.build_plan(controllers=["pi_kp1", "pi_still"], scenarios=["hold_side_70"], quick=True,
                        sweep=False, figures=False, out=tmp_path / "o")
    assert plan.runs["hold_side_70"].steps == 100 and plan.scenario("hold_side_70").warmup_s == 1.0
    res = B.bench(plan, progress=False)["results"]
    cell = res["summary"]["pi_still"]["hold_side_70"]
    assert cell["n_episodes"] == 2 and cell["vs_reference"]["az"]["n_episodes"] == 2
    spec = C.CampaignSpec(controllers=("pi_still",), plants=1, steps=100, warmup_s=1.0)
    assert spec.names == ("pi_still",)


def test_the_campaign_scores_a_trained_policy_under_its_name() -> None:
    spec = C.CampaignSpec(controllers=("pi_kp1", "ppo"), plants=1, steps=100, warmup_s=1.0,
                          ppo_model="runs/x/eval/best")
    assert spec.names == ("pi_kp1", "x/best") and spec.rows()[1].policy == "runs/x/eval/best"
    assert dataclasses.replace(spec, ppo_model=None).names == ("pi_kp1", "ppo")


def test_the_pi_takes_its_gains_from_the_environments_model() -> None:
    """A named gain set is the environment's model's (a user's model may differ from the
    shipped configs/model.yaml); a bare EnvConfig falls back to the shipped one."""
    from types import SimpleNamespace

    from dss14_env.baselines.pi import PIController
    from dss14_env.envs.config import load_env_config

    class Model:
        cfg = SimpleNamespace(gain_sets={"kp1": None})

        def gains(self, name):
            return (2.0, 1.5), (0.5, 0.4)

    cfg = load_env_config()
    env = SimpleNamespace(config=cfg, plants=SimpleNamespace(model=Model()))
    pi = PIController(env, "kp1")
    assert pi.kp.tolist() == [2.0, 1.5] and pi.ki.tolist() == [0.5, 0.4]
    shipped = PIController(cfg, "kp1")
    assert shipped.kp.tolist() == [1.0, 1.0] and shipped.ki.tolist() == [0.3, 0.3]
    with pytest.raises(ValueError, match="unknown gain set 'kp0.7'"):
        PIController(env, "kp0.7")


def test_the_campaigns_pi_gain_sets_come_from_the_rows() -> None:
    """A controller's PI gain set (the exact PI-loop stability column) is its row's argument,
    not read from its name."""
    from dss14_env.bench.campaign_report import pi_gain_set

    pis = {r.name: r.args[0] for r in catalog.CONTROLLER_ROWS if r.cls == "PIController"}
    assert pis == {"pi_kp1": "kp1", "pi_kp0.7": "kp0.7"}
    assert all(pi_gain_set(n) == g for n, g in pis.items()) and pi_gain_set("lqg") is None
