"""Plain stable-baselines3 on ``DSS14-v0``: train PPO with SB3's defaults and a few named changes,
then score the deterministic policy in the benchmark's holds against the report's PI.

A *setting* (:data:`SETTINGS`) names the environment keys, the PPO keywords that differ from
SB3's defaults and whether a ``VecNormalize`` wraps the environment.  Each training seed trains
one policy on ``DSS14-v0`` (one environment, one torch thread), timed (wall and process CPU
seconds), then plays the 50 km/h holds (``DSS14-HoldFront-v0`` scored on the elevation servo
error, ``DSS14-HoldSide-v0`` on the azimuth: 60-s episodes, 5-s warm-up) on evaluation seeds
that no training used; the PI (``pi_kp1``, on the registered ids as they are) plays the same
seeds.  The JSON written holds every seed's figures, the settings and the command line::

    python scripts/plain_sb3.py --setting snippet_std --seeds 0 1 2 --steps 150000 \
        --out docs/results/plain_sb3.json

(the committed file: seed 0 from ``docs/results/plain_sb3_runs/snippet_std_seed0.json`` with
``--runs-from``, the other settings' single-seed files summarised with ``--explored``; its
``command`` says which).  ``snippet_std`` is the README's example; ``defaults`` is SB3's PPO
untouched; :class:`LogCost` prototypes a bounded reward (``log_std``).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.baselines.base import Controller
from dss14_env.baselines.pi import PIController
from dss14_env.baselines.rollout import run_episode
from dss14_env.envs.presets import PRESETS

#: the holds scored and their loaded axis
HOLDS = {"hold_front": "el", "hold_side": "az"}

#: name -> env keys, PPO keywords (beyond SB3's defaults), VecNormalize on/off
SETTINGS: dict[str, dict[str, Any]] = {
    "defaults": {"env": {}, "ppo": {}, "normalize": False},
    "snippet": {"env": {"action_scale_deg_s": 0.02}, "ppo": {}, "normalize": True},
    "snippet_std": {"env": {"action_scale_deg_s": 0.02}, "ppo": {"policy_kwargs": {"log_std_init": -3.0}},
                    "normalize": True},
    "snippet_sde": {"env": {"action_scale_deg_s": 0.02},
                    "ppo": {"use_sde": True, "policy_kwargs": {"log_std_init": -3.0}}, "normalize": True},
    "snippet_std_n1024": {"env": {"action_scale_deg_s": 0.02},
                          "ppo": {"n_steps": 1024, "policy_kwargs": {"log_std_init": -3.0}},
                          "normalize": True},
    "log_std": {"env": {"action_scale_deg_s": 0.02}, "ppo": {"policy_kwargs": {"log_std_init": -3.0}},
                "normalize": True, "wrapper": "log"},
}

#: the bounded reward's termination penalty: 1 / (1 - 0.99), the per-step worst summed at discount 0.99
LOG_PENALTY = 100.0


class LogCost(gym.Wrapper):
    """Prototype of a bounded reward: ``-log(1 + c) / log(1 + c_max)`` in [-1, 0], ``c`` the
    environment's per-step cost, ``c_max`` its value at the error bound on both axes; the
    terminating step costs :data:`LOG_PENALTY` more (the discounted worst remainder at
    SB3's default discount 0.99).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        cfg = env.unwrapped.config
        self.penalty = float(cfg.termination_penalty)
        self.log_max = float(np.log1p(2.0 * (cfg.max_error_deg * 1e3 / cfg.error_scale_mdeg) ** 2))

    def step(self, action: Any) -> Any:
        """The environment's step with the bounded reward."""
        obs, r, term, trunc, info = self.env.step(action)
        cost = -float(r) - (self.penalty if term else 0.0)
        r = -float(np.log1p(max(cost, 0.0))) / self.log_max - (LOG_PENALTY if term else 0.0)
        return obs, r, term, trunc, info


class SB3Controller(Controller):
    """A trained SB3 model (and its observation normalisation) as a deterministic controller."""

    def __init__(self, model: PPO, norm: VecNormalize | None) -> None:
        super().__init__("plain SB3 PPO")
        self.model, self.norm = model, norm

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The model's deterministic action for one observation."""
        obs = np.asarray(observation, np.float32)
        if self.norm is not None:
            obs = self.norm.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=True)
        return np.asarray(action, np.float32)


def hold_figures(ctrl: Controller, env_kwargs: Mapping[str, Any], seeds: Sequence[int]) -> dict[str, Any]:
    """3σ (mdeg) of the loaded axis's servo error per hold and seed, and termination counts."""
    out: dict[str, Any] = {}
    for hold, axis in HOLDS.items():
        preset = PRESETS[hold]
        env = gym.make(preset.env_id, **dict(env_kwargs))
        eps = [run_episode(ctrl, env, s, preset.max_episode_steps, preset.warmup_s) for s in seeds]
        env.close()
        out[hold] = {"axis": axis,
                     "three_sigma_mdeg": [e["servo_error_mdeg"][axis]["three_sigma"] for e in eps],
                     "terminated": int(sum(bool(e["terminated"]) for e in eps)),
                     "accel_limit_hits": [int(e["limit_hits"]["accel"]) for e in eps]}
        out[hold]["mean_three_sigma_mdeg"] = float(np.mean(out[hold]["three_sigma_mdeg"]))
    return out


def train(setting: Mapping[str, Any], seed: int, steps: int) -> tuple[PPO, VecNormalize | None, dict]:
    """One training run of ``setting`` on ``DSS14-v0``, timed."""
    torch.set_num_threads(1)
    wrapper = LogCost if setting.get("wrapper") == "log" else None
    venv = make_vec_env("DSS14-v0", n_envs=1, seed=seed, env_kwargs=dict(setting["env"]),
                        wrapper_class=wrapper)
    norm = VecNormalize(venv) if setting["normalize"] else None
    model = PPO("MlpPolicy", norm or venv, seed=seed, **setting["ppo"])
    t0, c0 = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=steps)
    timing = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
    if norm is not None:
        norm.training = False
    return model, norm, timing


def summary(result: Mapping[str, Any]) -> dict[str, Any]:
    """The headline of one result file: setting, budget, and per seed the ratios to the PI,
    the holds' mean 3σ and the timing."""
    return {"setting": result["setting"], "definition": result["definition"], "steps": result["steps"],
            "eval_seeds": result["eval_seeds"],
            "runs": [{"seed": r["seed"], "ratio_to_pi": r["ratio_to_pi"], "wall_s": r["wall_s"],
                      "cpu_s": r["cpu_s"],
                      "mean_three_sigma_mdeg": {h: r["holds"][h]["mean_three_sigma_mdeg"] for h in HOLDS}}
                     for r in result["runs"]]}


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: train and score one setting over training seeds; write the JSON."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setting", choices=sorted(SETTINGS), required=True)
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--eval-seeds", type=int, nargs="+", default=[7000, 7001, 7002, 7003])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--runs-from", type=Path, nargs="*", default=[],
                   help="result files of this script with the same setting, steps and evaluation seeds "
                        "whose training seeds count too (their runs are copied)")
    p.add_argument("--explored", type=Path, nargs="*", default=[],
                   help="result files of this script from other settings, summarised under 'explored'")
    a = p.parse_args(argv)
    if a.steps < 1 or any(s >= 7000 for s in a.seeds) or any(s < 7000 for s in a.eval_seeds):
        p.error("--steps must be >= 1, training --seeds below 7000 and --eval-seeds 7000 or above")
    setting = SETTINGS[a.setting]
    explored = [summary(json.loads(f.read_text(encoding="utf-8"))) for f in a.explored]
    earlier = []
    for f in a.runs_from:
        old = json.loads(f.read_text(encoding="utf-8"))
        if (old["setting"], old["steps"], old["eval_seeds"]) != (a.setting, a.steps, a.eval_seeds):
            p.error(f"--runs-from {f}: setting, steps or evaluation seeds differ from this run's")
        earlier += old["runs"]
    pi = hold_figures(PIController(gym.make("DSS14-HoldFront-v0"), "kp1"), {}, a.eval_seeds)
    runs = list(earlier)
    for seed in a.seeds:
        model, norm, timing = train(setting, seed, a.steps)
        figs = hold_figures(SB3Controller(model, norm), setting["env"], a.eval_seeds)
        ratio = {h: figs[h]["mean_three_sigma_mdeg"] / pi[h]["mean_three_sigma_mdeg"] for h in HOLDS}
        runs.append({"seed": seed, **timing, "steps_per_cpu_s": a.steps / timing["cpu_s"],
                     "holds": figs, "ratio_to_pi": ratio})
        print(json.dumps({"seed": seed, **timing, "ratio_to_pi": ratio}), flush=True)
    result = {"setting": a.setting, "definition": setting, "steps": a.steps,
              "train_seeds": [r["seed"] for r in runs],
              "eval_seeds": a.eval_seeds, "pi_kp1": pi, "runs": runs, "explored": explored,
              "command": "python scripts/plain_sb3.py " + " ".join(sys.argv[1:] if argv is None else argv),
              "machine": {"cpu": platform.machine(), "python": platform.python_version(),
                          "torch": torch.__version__}}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
