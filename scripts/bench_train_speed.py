"""PPO training throughput: the batched DSS14 VecEnv against 8 x DummyVecEnv, in one run.

Builds the training VecEnv exactly as ``dss14 train`` does (dss14_env.agents.envs), with the
hyperparameters of a shipped config (default ``ppo``: the residual policy, 8 envs, n_steps
1024, batch 512, 10 epochs), and times ``model.learn`` for a few updates per variant:

* ``dummy``   -- ``vec_env: dummy``: 8 single environments in SB3's DummyVecEnv (as before);
* ``batched`` -- ``vec_env: batched``: one numpy vector env + the batched interface, same
  hyperparameters;
* ``batched-64`` -- batched with 64 envs x 128 steps (the same 8192 samples per update);
* with ``--light``, also ``dummy-light`` and ``batched-64-light``: the same, with a light
  learner (1 epoch, one minibatch per update), where the environment side can show its speed.

For each: environment steps per second of the whole training (rollouts + updates), and the
share of that wall time spent stepping the environment (the innermost VecEnv's
``step_wait``: the plant, limiter, observation, reward; for ``dummy`` the 8 Python
environments with their wrappers) and in the rollout's environment side (adds the policy
interface and VecNormalize).  The variants alternate over ``--repeats`` rounds (a shared
machine's load then hits all of them alike); medians and per-round ratios to ``dummy`` are
printed, measured in this one run.

    python scripts/bench_train_speed.py [--config ppo] [--updates 3] [--repeats 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from typing import Any

import numpy as np


class _Timer:
    """Accumulates wall time of a wrapped method."""

    def __init__(self, obj: Any, name: str) -> None:
        self.total = 0.0
        fn = getattr(obj, name)

        def timed(*a: Any, **k: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                self.total += time.perf_counter() - t0

        setattr(obj, name, timed)


def _innermost(venv: Any) -> Any:
    while hasattr(getattr(venv, "venv", None), "step_wait"):
        venv = venv.venv
    return venv


def measure(cfg: Any, updates: int) -> dict[str, Any]:
    import torch
    from stable_baselines3.common.vec_env import VecNormalize
    from threadpoolctl import threadpool_limits

    from dss14_env.agents.algos import algo_class, algo_kwargs, policy_kwargs
    from dss14_env.agents.envs import check_env, make_train_vec_env, vec_env_kind

    torch.set_num_threads(cfg.torch_threads)
    plan, _, _, env_config = check_env(cfg)
    kind = vec_env_kind(cfg, plan)
    venv = VecNormalize(make_train_vec_env(cfg, plan, env_config, None), gamma=cfg.gamma)
    inner = _innermost(venv)
    env_t = _Timer(inner, "step_wait")
    side_t = _Timer(venv, "step_wait")
    model = algo_class(cfg.algo)("MlpPolicy", venv, policy_kwargs=policy_kwargs(cfg),
                                 seed=cfg.seed, device="cpu", verbose=0, **algo_kwargs(cfg))
    steps = updates * cfg.n_steps * cfg.n_envs
    with threadpool_limits(limits=1):
        t0 = time.perf_counter()
        model.learn(total_timesteps=steps)
        wall = time.perf_counter() - t0
    venv.close()
    return {"vec_env": kind, "n_envs": cfg.n_envs, "n_steps": cfg.n_steps,
            "batch_size": cfg.batch_size, "n_epochs": cfg.n_epochs, "steps": steps,
            "wall_s": wall, "steps_per_s": steps / wall, "env_share": env_t.total / wall,
            "env_side_share": side_t.total / wall,
            "env_us_per_step": 1e6 * env_t.total / steps}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="ppo", help="shipped config name or YAML (default ppo)")
    ap.add_argument("--env", default=None, metavar="ID",
                    help="instead of --config: the shipped PPO hyperparameters of this id "
                    "(configs/hyperparams/ppo.yml)")
    ap.add_argument("--updates", type=int, default=3, help="PPO updates per variant (default 3)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="rounds; the variants alternate within a round, medians are reported "
                    "(default 3)")
    ap.add_argument("--light", action="store_true",
                    help="add the light-learner variants (1 epoch, one minibatch per update)")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = ap.parse_args()

    from dss14_env.agents.config import load_config
    from dss14_env.agents.hyperparams import load_hyperparams

    cfg0 = load_hyperparams("ppo", args.env) if args.env else load_config(args.config)
    base = cfg0.replace(eval_freq=0, checkpoint_freq=0, progress_bar=False,
                                            verbose=0)
    samples = base.n_steps * base.n_envs
    variants = [("dummy", base.replace(vec_env="dummy")),
                ("batched", base.replace(vec_env="batched")),
                ("batched-64", base.replace(vec_env="batched", n_envs=64,
                                            n_steps=max(samples // 64, 1)))]
    if args.light:
        variants += [(f"{name}-light", cfg.replace(n_epochs=1, batch_size=cfg.n_steps * cfg.n_envs))
                     for name, cfg in (variants[0], variants[2])]
    runs: list[dict[str, Any]] = []
    for rep in range(args.repeats):  # alternate the variants: a shared machine's load hits all
        for name, cfg in variants:
            r = measure(cfg, args.updates)
            r.update(variant=name, repeat=rep)
            runs.append(r)
            print(f"[{rep}] {name:11s} {r['n_envs']:3d} envs x {r['n_steps']:5d} steps: "
                  f"{r['steps_per_s']:8.0f} steps/s, env {100 * r['env_share']:5.1f} % "
                  f"({r['env_us_per_step']:.1f} us/step), env side incl. interface and "
                  f"normalisation {100 * r['env_side_share']:5.1f} %", flush=True)
    rows = []
    for name, _ in variants:
        mine = [r for r in runs if r["variant"] == name]
        rows.append({"variant": name, "n_envs": mine[0]["n_envs"], "n_steps": mine[0]["n_steps"],
                     **{k: float(np.median([r[k] for r in mine]))
                        for k in ("steps_per_s", "env_share", "env_side_share", "env_us_per_step")},
                     "steps_per_s_all": [r["steps_per_s"] for r in mine]})
    ref = rows[0]["steps_per_s"]
    for r in rows:
        r["speedup_vs_dummy"] = r["steps_per_s"] / ref
        # per round, each variant against that round's dummy run
        r["speedup_per_round"] = [a / b for a, b in zip(r["steps_per_s_all"],
                                                       rows[0]["steps_per_s_all"], strict=True)]
    print("medians: " + "; ".join(
        f"{r['variant']} {r['steps_per_s']:.0f} steps/s ({r['speedup_vs_dummy']:.2f}x dummy, "
        f"per round {min(r['speedup_per_round']):.2f}-{max(r['speedup_per_round']):.2f}x), env "
        f"{100 * r['env_share']:.1f} %, env side {100 * r['env_side_share']:.1f} %" for r in rows))
    if args.json:
        meta = {"config": args.env or args.config, "updates": args.updates, "cpu_count": os.cpu_count(),
                "machine": platform.processor() or platform.machine(),
                "load_avg": list(os.getloadavg()), "numpy": np.__version__}
        with open(args.json, "w") as fh:
            json.dump({"meta": meta, "rows": rows, "runs": runs}, fh, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
