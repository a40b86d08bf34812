"""The one catalog: every list of controllers and scenarios derives from its rows, and a new
controller or scenario is its module (or preset) plus its row."""

from __future__ import annotations

import dataclasses
import importlib
import json
import sys

import gymnasium as gym
import pytest

from dss14_env import cli
from dss14_env.agents import evaluation
from dss14_env.bench import campaign as C
from dss14_env.bench import catalog
from dss14_env.bench import figures as F
from dss14_env.bench import plan as P
from dss14_env.envs.presets import PRESETS


@pytest.mark.parametrize("row", [r for r in catalog.CONTROLLER_ROWS if r.policy is None],
                         ids=lambda r: r.name)
def test_a_rows_batchable_flag_is_its_classes(row) -> None:
    cls = getattr(importlib.import_module(row.module), row.cls)
    assert row.batchable == bool(getattr(cls, "batchable", False))


def test_policy_rows_name_shipped_policies_that_load() -> None:
    for row in catalog.CONTROLLER_ROWS:
        if row.policy is not None:
            assert row.batchable and row.policy_problem() is None, row.name


def test_results_name_a_shipped_policy_by_its_place_in_the_package_not_a_machines_folder(tmp_path) -> None:
    """A results file records ``agents/policies/<name>`` for a shipped policy wherever the package
    is installed, and a user's policy path as given."""
    assert catalog.CONTROLLERS["ppo_plain"].policy_label() == "agents/policies/ppo_plain"
    assert catalog.policy_row("runs/mine").policy_label() == "runs/mine"
    assert catalog.CONTROLLERS["pi_kp1"].policy_label() is None
    plan = P.build_plan(controllers=["pi_kp1", "ppo_plain"], scenarios=["hold_front"], seeds=1,
                        sweep=False, figures=False, out=tmp_path / "b")
    assert plan.as_dict()["policies"] == {"ppo_plain": "agents/policies/ppo_plain"}


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
    assert {F.scenario_group(s) for s in scens} == set(catalog.GROUPS)
    assert all(F.scenario_group(r.name) == r.group for r in catalog.SCENARIO_ROWS)
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


#: a module from outside the package: a controller that holds the command still and a scenario
#: in one row, registered with the catalog's registration API when it is imported
PLUGIN = '''
import numpy as np

from dss14_env.baselines.base import Controller
from dss14_env.bench.catalog import Budget, ControllerRow, ScenarioRow, register_controller, register_scenario
from dss14_env.envs.presets import Preset


class Still(Controller):
    """Commands no motion."""

    def __init__(self, env):
        super().__init__("still")

    def act(self, observation):
        return np.zeros(2, np.float32)


register_controller(ControllerRow("still", __name__, "Still", "commands no motion", batchable=False,
                                  bench=False))
register_scenario(ScenarioRow(
    "hold_side_70", Budget(60.0, 8, 1), Budget(2.0, 2, 1), bench=False,
    preset=Preset("DSS14-HoldSide70-v0",
                  {"scenario": "hold", "wind_speed_kmh": 70.0, "wind_direction": "side"}, 3000, 1.0,
                  "hold, 70 km/h side wind", "strong side wind", ("az",))))
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """The plugin module on the path; its rows removed again afterwards."""
    (tmp_path / "dss14_test_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "dss14_test_plugin"
    for name in ("still", "hold_side_70"):
        if name in catalog.CONTROLLERS or name in catalog.SCENARIOS:
            catalog.unregister(name)
    sys.modules.pop("dss14_test_plugin", None)  # imported again (and registering) by the next test


def test_a_registered_controller_and_scenario_run_through_dss14_bench(plugin, capsys, tmp_path) -> None:
    """A controller (its module) and a scenario (one row) registered from outside the package
    reach the help, the tables, the plan, the campaign and ``dss14 bench`` itself."""
    out = tmp_path / "out"
    rc = cli.main(["--plugin", plugin, "bench", "--controllers", "pi_kp1", "still", "--scenarios",
                   "hold_side_70", "--quick", "--no-sweep", "--no-figures", "--no-progress",
                   "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    res = json.loads((out / "results.json").read_text())
    assert res["meta"]["controllers"] == ["pi_kp1", "still"] and res["meta"]["scenarios"] == ["hold_side_70"]
    cells = res["summary"]
    assert cells["pi_kp1"]["hold_side_70"]["n_episodes"] == 2
    assert cells["still"]["hold_side_70"]["n_episodes"] == 1
    # holding still in 70 km/h side wind: the wind alone moves the dish, the PI pulls it back
    still = cells["still"]["hold_side_70"]["servo_error_mdeg"]["az"]["three_sigma"]["value"]
    pi = cells["pi_kp1"]["hold_side_70"]["servo_error_mdeg"]["az"]["three_sigma"]["value"]
    assert still > pi > 0.0
    capsys.readouterr()
    for command in ("bench", "campaign"):
        assert "still" in _help(capsys, command)
    assert "hold_side_70" in _help(capsys, "bench")
    assert "`still`" in catalog.controllers_table() and "`hold_side_70`" in catalog.scenarios_table()
    assert P.LOADED_AXES["hold_side_70"] == ("az",) and P.QUICK_BUDGETS["hold_side_70"].episodes == 2
    assert "hold_side_70" not in P.build_plan(sweep=False).scenarios  # bench=False: not a default
    assert gym.spec("DSS14-HoldSide70-v0").kwargs["wind_speed_kmh"] == 70.0
    assert C.CampaignSpec(controllers=("still",), plants=1, steps=100, warmup_s=1.0).names == ("still",)
    catalog.unregister("hold_side_70")  # its preset's id goes with it: the manual lists every id left
    assert "hold_side_70" not in catalog.SCENARIOS and "DSS14-HoldSide70-v0" not in gym.registry


def test_registration_refuses_bad_rows_in_one_line(plugin) -> None:
    importlib.import_module(plugin)
    row = catalog.CONTROLLERS["still"]
    cases = [
        (lambda: catalog.register_controller(row), "controller 'still' is registered already"),
        (lambda: catalog.register_controller(dataclasses.replace(row, name="a b")),
         "controller name: letters"),
        (lambda: catalog.register_controller(dataclasses.replace(row, name="x", cls="Nope")),
         "controller 'x': dss14_test_plugin.Nope cannot be imported"),
        (lambda: catalog.register_controller(dataclasses.replace(row, name="x", batchable=True)),
         "controller 'x': Still does not act on batches"),
        (lambda: catalog.register_scenario(catalog.ScenarioRow("y", catalog.Budget(1.0, 1, 0),
                                                               catalog.Budget(1.0, 0, 0), preset="hold")),
         "scenario 'y': quick budget"),
        (lambda: catalog.register_scenario(catalog.ScenarioRow("y", catalog.Budget(1.0, 1, 0),
                                                               catalog.Budget(1.0, 1, 0), preset="hover")),
         "scenario 'y': unknown preset 'hover'"),
        (lambda: catalog.register_scenario(catalog.ScenarioRow("y", catalog.Budget(1.0, 1, 0),
                                                               catalog.Budget(1.0, 1, 0), preset="hold",
                                                               env={"wind_speed_kmh": 500.0})),
         "scenario 'y': .*wind_speed_kmh"),
        (lambda: catalog.unregister("pi_kp1"), "'pi_kp1' is a shipped row"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError, match=message) as info:
            call()
        assert "\n" not in str(info.value)
    assert "x" not in catalog.CONTROLLERS and "y" not in catalog.SCENARIOS


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
