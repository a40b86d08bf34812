"""The README's plain stable-baselines3 example is the setting measured in
docs/results/plain_sb3.json (scripts/plain_sb3.py), with the budget it states; the measured file
holds every training seed's figures.  (The example itself runs, shortened, in
tests/test_docs_examples.py.)"""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("plain_sb3", ROOT / "scripts" / "plain_sb3.py")
ps = importlib.util.module_from_spec(_spec)
sys.modules["plain_sb3"] = ps
_spec.loader.exec_module(ps)

RESULT = json.loads((ROOT / "docs" / "results" / "plain_sb3.json").read_text(encoding="utf-8"))


def _example() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", text, re.M | re.S)
    found = [b for b in blocks if "stable_baselines3" in b and "PPO(" in b]
    assert len(found) == 1, "the README has one plain stable-baselines3 example"
    return found[0]


def test_the_readme_example_is_the_measured_setting() -> None:
    code = _example()
    setting = ps.SETTINGS[RESULT["setting"]]
    assert RESULT["definition"] == json.loads(json.dumps(setting))
    assert f'make_vec_env("{setting.get("env_id", "DSS14-v0")}"' in code
    assert "torch.set_num_threads(1)" in code
    for key, value in setting["env"].items():
        assert re.search(rf'"{key}":\s*{re.escape(repr(value))}\b', code), key
    ppo = dict(setting["ppo"])
    for key, value in ppo.pop("policy_kwargs", {}).items():
        assert re.search(rf'"{key}":\s*{re.escape(repr(value))}\b', code), key
    for key, value in ppo.items():  # every other PPO keyword named, the rest SB3's defaults
        assert re.search(rf"\b{key}={re.escape(repr(value))}\b", code), key
    named = re.findall(r"\b(\w+)=", code.split("PPO(", 1)[1].split(")")[0])
    assert sorted(named) == sorted([*setting["ppo"], "seed"])
    assert ("VecNormalize(" in code) == bool(setting["normalize"])
    if isinstance(setting["normalize"], dict):
        for key, value in setting["normalize"].items():
            assert re.search(rf"\b{key}={re.escape(repr(value))}", code), key
    steps = int(re.search(r"total_timesteps=([0-9_]+)", code).group(1).replace("_", ""))
    assert steps == RESULT["steps"]


def test_the_result_holds_three_training_seeds_scored_on_unseen_seeds() -> None:
    seeds = [r["seed"] for r in RESULT["runs"]]
    assert len(set(seeds)) >= 3 and seeds == RESULT["train_seeds"]
    assert min(RESULT["eval_seeds"]) >= 7000 > max(seeds)
    for r in RESULT["runs"]:
        for hold in ps.HOLDS:
            mine = r["holds"][hold]["mean_three_sigma_mdeg"]
            assert r["ratio_to_pi"][hold] == mine / RESULT["pi_kp1"][hold]["mean_three_sigma_mdeg"]
            assert len(r["holds"][hold]["three_sigma_mdeg"]) == len(RESULT["eval_seeds"])


@pytest.mark.parametrize("name", ["exp", "log"])
def test_the_bounded_reward_prototypes_stay_in_their_range(name: str) -> None:
    env = ps.WRAPPERS[name](gym.make("DSS14-v0", action_scale_deg_s=0.25))
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    rewards = []
    for _ in range(400):  # full-scale random commands: errors grow towards the bound
        _, r, term, trunc, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        rewards.append(r)
        if term or trunc:
            break
    live = np.array(rewards[:-1] if term else rewards)
    assert np.all((live <= 0.0) & (live >= -1.0)) and live.min() < live.max()
    if term:
        assert -1.0 - ps.LOG_PENALTY <= rewards[-1] <= -ps.LOG_PENALTY


def test_the_unit_reward_is_the_environments_over_its_value_at_the_bound() -> None:
    kw = {"action_scale_deg_s": 0.02, "max_error_deg": 0.05}
    plain, unit = gym.make("DSS14-v0", **kw), ps.UnitCost(gym.make("DSS14-v0", **kw))
    plain.reset(seed=3)
    unit.reset(seed=3)
    for a in np.linspace(-1.0, 1.0, 20):
        _, r, *_ = plain.step(np.full(2, a, np.float32))
        _, u, *_ = unit.step(np.full(2, a, np.float32))
        assert u == pytest.approx(r / (2 * (50.0 / 10.0) ** 2))


def test_the_holds_are_scored_with_the_interface_keys_only() -> None:
    keys = {"action_scale_deg_s": 0.02, "max_error_deg": 0.05, "action_change_weight": 0.0064}
    assert ps.interface(keys) == {"action_scale_deg_s": 0.02}


def test_the_readme_states_the_measured_ratios_and_budget() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for hold in ps.HOLDS:
        ratios = [r["ratio_to_pi"][hold] for r in RESULT["runs"]]
        assert f"{min(ratios):.2f}–{max(ratios):.2f}×" in text, hold
    cpu = [r["cpu_s"] for r in RESULT["runs"]]
    assert f"{min(cpu):.0f}–{max(cpu):.0f} CPU-s a run" in text
    assert f"Budget {RESULT['steps'] // 1000} k steps" in text
