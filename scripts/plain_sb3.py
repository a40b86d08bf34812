"""Plain stable-baselines3 on ``DSS14-v0``: train PPO with SB3's defaults and a few named changes,
then score the deterministic policy in the benchmark's holds against the report's PI.

A *setting* (:data:`SETTINGS`) names the environment keys, the PPO keywords that differ from
SB3's defaults and whether (and how) a ``VecNormalize`` wraps the environment.  Each training
seed trains one policy on ``DSS14-v0`` (one environment, one torch thread), timed (wall and
process CPU seconds of ``learn``, without the learning curve's scoring), then plays the 50 km/h
holds (``DSS14-HoldFront-v0`` scored on the elevation servo error, ``DSS14-HoldSide-v0`` on the
azimuth: 60-s episodes, 5-s warm-up) on evaluation seeds that no training used, with the
setting's interface keys (:data:`INTERFACE_KEYS`) and the registered ids' reward and episode
end; the PI (``pi_kp1``, on the registered ids as they are) plays the same seeds.  Each run also
records why it learned what it did: the policy's proportional gain about the zero observation
(:func:`error_gain`), the ``VecNormalize`` statistics (:func:`normalisation`) and, with
``--curve-every``, a learning curve on a seed of its own (:class:`Curve`).  The JSON written
holds every seed's figures, the settings and the command line::

    python scripts/plain_sb3.py --setting snippet_bound --seeds 0 1 2 --steps 150000 \
        --curve-every 25000 --out docs/results/plain_sb3_runs/snippet_bound.json

The committed ``docs/results/plain_sb3.json`` takes those runs with ``--runs-from`` (no new
training: ``--seeds`` empty) and summarises the other settings' files under ``explored``
(``--explored``); its ``command`` says which.  ``snippet_bound`` is the README's example;
``defaults`` is SB3's PPO untouched; :class:`LogCost` and :class:`ExpCost` prototype bounded
rewards, :class:`UnitCost` the reward in units of its value at the error bound.
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
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.baselines.base import Controller
from dss14_env.baselines.pi import PIController
from dss14_env.baselines.rollout import run_episode
from dss14_env.envs.presets import PRESETS

#: the holds scored and their loaded axis
HOLDS = {"hold_front": "el", "hold_side": "az"}

#: name -> env keys, PPO keywords (beyond SB3's defaults), VecNormalize on/off (or its keywords);
#: optional: ``env_id`` the training id (default ``DSS14-v0``), ``wrapper`` a reward prototype
#: (:data:`WRAPPERS`).  ``snippet_bound`` is the README's example; the others are what was tried
#: on the way (``docs/results/plain_sb3.json``, ``explored``)
S02 = {"action_scale_deg_s": 0.02}
ACW = {"action_scale_deg_s": 0.02, "action_change_weight": 0.0064}
BOUND = {"max_error_deg": 0.05}
STD1, STD3 = {"policy_kwargs": {"log_std_init": -1.0}}, {"policy_kwargs": {"log_std_init": -3.0}}
REWNORM = {"norm_obs": False}
SETTINGS: dict[str, dict[str, Any]] = {
    "defaults": {"env": {}, "ppo": {}, "normalize": False},
    "snippet_bound": {"env": {**S02, **BOUND}, "ppo": STD1, "normalize": REWNORM},
    # without the 50-mdeg episode end
    "snippet": {"env": S02, "ppo": {}, "normalize": True},
    "snippet_std": {"env": S02, "ppo": STD3, "normalize": True},
    "snippet_sde": {"env": S02, "ppo": {"use_sde": True, **STD3}, "normalize": True},
    "snippet_std_n1024": {"env": S02, "ppo": {"n_steps": 1024, **STD3}, "normalize": True},
    "log_std": {"env": S02, "ppo": STD3, "normalize": True, "wrapper": "log"},
    "snippet_std_rewnorm": {"env": S02, "ppo": STD3, "normalize": REWNORM},
    "exp_raw": {"env": S02, "ppo": STD3, "normalize": False, "wrapper": "exp"},
    "exp_full_scale": {"env": {}, "ppo": STD3, "normalize": False, "wrapper": "exp"},
    "rewnorm_acw": {"env": ACW, "ppo": {"n_steps": 512, **STD1}, "normalize": REWNORM},
    "acw_exp": {"env": ACW, "ppo": {"n_steps": 512, **STD1}, "normalize": False, "wrapper": "exp"},
    "acw_log": {"env": ACW, "ppo": {"n_steps": 512, **STD1}, "normalize": False, "wrapper": "log"},
    "rewnorm_acw_n256": {"env": ACW, "ppo": {"n_steps": 256, **STD1}, "normalize": REWNORM},
    "rewnorm_acw_s005": {"env": {"action_scale_deg_s": 0.05, "action_change_weight": 0.04},
                         "ppo": {"n_steps": 512, "policy_kwargs": {"log_std_init": -1.6}},
                         "normalize": REWNORM},
    "rewnorm_acw_hold": {"env_id": "DSS14-Hold-v0", "env": ACW, "ppo": {"n_steps": 512, **STD1},
                         "normalize": REWNORM},
    # with it
    "bound_acw_n512": {"env": {**ACW, **BOUND}, "ppo": {"n_steps": 512, **STD1}, "normalize": REWNORM},
    "bound_acw": {"env": {**ACW, **BOUND}, "ppo": STD1, "normalize": REWNORM},
    "bound_acw_normobs": {"env": {**ACW, **BOUND}, "ppo": STD1, "normalize": True},
    "bound_acw_std3": {"env": {**ACW, **BOUND}, "ppo": STD3, "normalize": REWNORM},
    "snippet_std_bound": {"env": {**S02, **BOUND}, "ppo": STD3, "normalize": True},
    "bound_raw": {"env": {**S02, **BOUND}, "ppo": STD1, "normalize": False},
    "bound_unit": {"env": {**S02, **BOUND}, "ppo": STD1, "normalize": False, "wrapper": "unit"},
    "bound_raw_p100": {"env": {**S02, **BOUND, "termination_penalty": 100.0}, "ppo": STD1,
                       "normalize": False},
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


class ExpCost(gym.Wrapper):
    """Prototype of a bounded reward that keeps the quadratic cost's scale near zero:
    ``exp(-c) - 1`` in [-1, 0], ``c`` the environment's per-step cost (``-c`` for ``c`` << 1,
    ``-1`` for errors well beyond ``error_scale_mdeg``); the terminating step costs
    :data:`LOG_PENALTY` more.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.penalty = float(env.unwrapped.config.termination_penalty)

    def step(self, action: Any) -> Any:
        """The environment's step with the bounded reward."""
        obs, r, term, trunc, info = self.env.step(action)
        cost = -float(r) - (self.penalty if term else 0.0)
        return obs, float(np.expm1(-max(cost, 0.0))) - (LOG_PENALTY if term else 0.0), term, trunc, info


class UnitCost(gym.Wrapper):
    """Prototype of a reward in units of its value at the error bound: the environment's reward
    divided by ``2 (max_error / error_scale)^2`` (-1 with both axes at the bound; the
    termination penalty is divided alike)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        cfg = env.unwrapped.config
        self.unit = float(2.0 * (cfg.max_error_deg * 1e3 / cfg.error_scale_mdeg) ** 2)

    def step(self, action: Any) -> Any:
        """The environment's step with the rescaled reward."""
        obs, r, term, trunc, info = self.env.step(action)
        return obs, float(r) / self.unit, term, trunc, info


#: the reward prototypes by name
WRAPPERS: dict[str, type[gym.Wrapper]] = {"log": LogCost, "exp": ExpCost, "unit": UnitCost}


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


def error_gain(ctrl: SB3Controller, env_kwargs: Mapping[str, Any]) -> list[float]:
    """The deterministic policy's proportional gain per axis about the zero observation: the
    commanded rate per servo error, 1/s, from a central difference of +-1 mdeg (a hold with the
    PI's precision needs about 1-4 /s: a memoryless ``rate = k e`` holds the 50 km/h holds within
    the PI's 3σ there)."""
    env = gym.make("DSS14-v0", **dict(env_kwargs))
    cfg = env.unwrapped.config
    env.close()
    unit_deg = cfg.error_scale_mdeg * 1e-3
    gains = []
    for axis in range(2):
        obs = np.zeros((2, 12), np.float32)
        obs[0, axis], obs[1, axis] = 1e-3 / unit_deg, -1e-3 / unit_deg
        da = ctrl.act(obs[0])[axis] - ctrl.act(obs[1])[axis]
        gains.append(float(da * cfg.action_scale_deg_s / 2e-3))
    return gains


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


#: the environment keys of the policy's interface (what it sees and commands): the holds are
#: scored with these from a setting, and with the registered ids' reward and episode end
INTERFACE_KEYS = ("action_scale_deg_s", "error_scale_mdeg")


def interface(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The interface keys of ``env_kwargs``."""
    return {k: v for k, v in env_kwargs.items() if k in INTERFACE_KEYS}


#: the seed of the learning curve's holds (neither a training nor an evaluation seed)
CURVE_SEED = 5000


class Curve(BaseCallback):
    """Every ``every`` steps: the deterministic policy's 3σ in both holds on :data:`CURVE_SEED`
    (mdeg, loaded axis) and the exploration's standard deviation per axis (action units), for
    the learning curve; nothing is selected from it."""

    def __init__(self, every: int, env_kwargs: Mapping[str, Any]) -> None:
        super().__init__()
        self.every, self.env_kwargs, self.points, self.norm = every, env_kwargs, [], None
        self.wall_s = self.cpu_s = 0.0  # its own time, taken out of the training's

    def _on_step(self) -> bool:
        if self.every and self.num_timesteps % self.every == 0:
            t0, c0 = time.perf_counter(), time.process_time()
            ctrl = SB3Controller(self.model, self.norm)
            figs = hold_figures(ctrl, self.env_kwargs, [CURVE_SEED])
            std = np.exp(self.model.policy.log_std.detach().numpy()).tolist()
            self.points.append([self.num_timesteps] + [figs[h]["mean_three_sigma_mdeg"] for h in HOLDS] + std)
            print(json.dumps({"curve": self.points[-1]}), flush=True)
            self.wall_s += time.perf_counter() - t0
            self.cpu_s += time.process_time() - c0
        return True


def train(setting: Mapping[str, Any], seed: int, steps: int,
          curve_every: int = 0) -> tuple[PPO, VecNormalize | None, dict]:
    """One training run of ``setting`` on ``DSS14-v0``, timed."""
    torch.set_num_threads(1)
    wrapper = WRAPPERS[setting["wrapper"]] if "wrapper" in setting else None
    venv = make_vec_env(setting.get("env_id", "DSS14-v0"), n_envs=1, seed=seed,
                        env_kwargs=dict(setting["env"]), wrapper_class=wrapper)
    norm_kw = setting["normalize"]
    norm = VecNormalize(venv, **(norm_kw if isinstance(norm_kw, dict) else {})) if norm_kw else None
    model = PPO("MlpPolicy", norm or venv, seed=seed, **setting["ppo"])
    t0, c0 = time.perf_counter(), time.process_time()
    curve = Curve(curve_every, interface(setting["env"]))
    curve.norm = norm
    model.learn(total_timesteps=steps, callback=curve)
    timing: dict[str, Any] = {"wall_s": time.perf_counter() - t0 - curve.wall_s,
                              "cpu_s": time.process_time() - c0 - curve.cpu_s}
    if curve_every:
        timing["curve_steps_front_side_mdeg_std"] = curve.points
    if norm is not None:
        norm.training = False
        timing["normalisation"] = normalisation(norm)
    return model, norm, timing


def normalisation(norm: VecNormalize) -> dict[str, Any]:
    """The ``VecNormalize`` statistics at the end of training: the observation's running standard
    deviations (what one unit of each normalised input is in the environment's units) and the
    discounted return's (what the rewards are divided by)."""
    out: dict[str, Any] = {"return_std": float(np.sqrt(norm.ret_rms.var + norm.epsilon))}
    if norm.norm_obs:
        out["obs_std"] = [float(v) for v in np.sqrt(norm.obs_rms.var + norm.epsilon)]
    return out


#: the diagnostics a run may carry, copied into its summary where present
DIAGNOSTICS = ("error_gain_per_s", "normalisation", "curve_steps_front_side_mdeg",
               "curve_steps_front_side_mdeg_std", "timing_note")


def summary(result: Mapping[str, Any]) -> dict[str, Any]:
    """The headline of one result file: setting, budget, and per seed the ratios to the PI,
    the holds' mean 3σ, the timing and the diagnostics (:data:`DIAGNOSTICS`) it has."""
    return {"setting": result["setting"], "definition": result["definition"], "steps": result["steps"],
            "eval_seeds": result["eval_seeds"],
            "runs": [{"seed": r["seed"], "ratio_to_pi": r["ratio_to_pi"], "wall_s": r["wall_s"],
                      "cpu_s": r["cpu_s"],
                      "mean_three_sigma_mdeg": {h: r["holds"][h]["mean_three_sigma_mdeg"] for h in HOLDS},
                      **{k: r[k] for k in DIAGNOSTICS if k in r}}
                     for r in result["runs"]]}


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: train and score one setting over training seeds; write the JSON."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setting", choices=sorted(SETTINGS), required=True)
    p.add_argument("--seeds", type=int, nargs="*", default=[0],
                   help="training seeds to train now (none: only --runs-from's)")
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--curve-every", type=int, default=0,
                   help="score the holds on the curve's seed every this many steps (0: never; timed with "
                        "the training)")
    p.add_argument("--eval-seeds", type=int, nargs="+", default=[7000, 7001, 7002, 7003])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--runs-from", type=Path, nargs="*", default=[],
                   help="result files of this script with the same setting, steps and evaluation seeds "
                        "whose training seeds count too (their runs are copied)")
    p.add_argument("--explored", type=Path, nargs="*", default=[],
                   help="result files of this script from other settings, summarised under 'explored'")
    a = p.parse_args(argv)
    if not a.seeds and not a.runs_from:
        p.error("--seeds: give training seeds or --runs-from files")
    if a.steps < 1 or any(s >= 7000 for s in a.seeds) or any(s < 7000 for s in a.eval_seeds):
        p.error("--steps must be >= 1, training --seeds below 7000 and --eval-seeds 7000 or above")
    setting = SETTINGS[a.setting]
    explored = [summary(json.loads(f.read_text(encoding="utf-8"))) for f in a.explored]
    earlier = []
    for f in a.runs_from:
        old = json.loads(f.read_text(encoding="utf-8"))
        mine = (a.setting, json.loads(json.dumps(setting)), a.steps, a.eval_seeds)
        if (old["setting"], old["definition"], old["steps"], old["eval_seeds"]) != mine:
            p.error(f"--runs-from {f}: setting, definition, steps or evaluation seeds differ from this run's")
        earlier += old["runs"]
    seeds = [r["seed"] for r in earlier] + list(a.seeds)
    if len(set(seeds)) != len(seeds):
        p.error(f"--seeds: training seed counted twice: {seeds}")
    pi = hold_figures(PIController(gym.make("DSS14-HoldFront-v0"), "kp1"), {}, a.eval_seeds)
    runs = list(earlier)
    for seed in a.seeds:
        model, norm, timing = train(setting, seed, a.steps, a.curve_every)
        figs = hold_figures(SB3Controller(model, norm), interface(setting["env"]), a.eval_seeds)
        ratio = {h: figs[h]["mean_three_sigma_mdeg"] / pi[h]["mean_three_sigma_mdeg"] for h in HOLDS}
        timing["error_gain_per_s"] = error_gain(SB3Controller(model, norm), setting["env"])
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
