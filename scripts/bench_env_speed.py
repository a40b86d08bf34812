"""Speed of the DSS14 environments: single-env steps/s against Pendulum-v1, and the batched
vector env's env-steps/s.

Run on 2 cores (the figures in docs/env.md were taken like this)::

    taskset -c 0,1 python scripts/bench_env_speed.py

The single environments are made with ``gymnasium.make`` (so all carry the same standard
wrappers) and stepped with actions drawn beforehand (uniform over the action space); an
episode end triggers a reset, which is counted in the time.  The runs of the environments
alternate, ``--repeats`` rounds, and each figure is the best of its runs (the one least
disturbed by other load on the machine).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository's dss14_env first
import dss14_env  # noqa: E402,F401  (registers DSS14-v0)


class _SingleRun:
    """One ``gymnasium.make`` environment with actions drawn beforehand."""

    def __init__(self, env_id: str, n_steps: int, seed: int = 0) -> None:
        self.env = gym.make(env_id)
        rng = np.random.default_rng(seed)
        space = self.env.action_space
        self.actions = rng.uniform(space.low, space.high, (n_steps,) + space.shape).astype(space.dtype)
        for s in range(30):  # warm-up: build the model and the plants of the variant's wind grid
            self.env.reset(seed=seed + s)
        for a in self.actions[:1000]:
            self.env.step(a)
        self.env.reset(seed=seed)

    def rate(self) -> float:
        """Steps/s of one pass over the actions (episode ends reset, inside the timing)."""
        env, actions = self.env, self.actions
        t0 = time.perf_counter()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        return actions.shape[0] / (time.perf_counter() - t0)


def single_env_rates(env_ids: list[str], n_steps: int, repeats: int) -> dict[str, float]:
    """Best steps/s of each environment; the runs of the ids are interleaved ``repeats`` times,
    so a change of the machine's load affects them alike."""
    runs = {env_id: _SingleRun(env_id, n_steps) for env_id in env_ids}
    best = dict.fromkeys(env_ids, 0.0)
    for _ in range(repeats):
        for env_id, run in runs.items():
            best[env_id] = max(best[env_id], run.rate())
    return best


def vector_env_rate(env_id: str, num_envs: int, n_steps: int, repeats: int, seed: int = 0) -> float:
    """Best env-steps/s of the ``vector_entry_point`` vector env over ``repeats`` runs."""
    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-0.01, 0.01, (64, num_envs, 2)).astype(np.float32)
    envs.reset(seed=seed)
    for i in range(20):
        envs.step(actions[i % 64])
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        for i in range(n_steps):
            envs.step(actions[i % 64])
        best = max(best, num_envs * n_steps / (time.perf_counter() - t0))
    envs.close()
    return best


def main() -> None:
    """Print the single-env rates, their ratios to Pendulum-v1 and the vector-env rates."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=30000, help="single-env steps per run")
    ap.add_argument("--vec-steps", type=int, default=1000, help="vector-env steps per run")
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rates = single_env_rates(["Pendulum-v1", "DSS14-v0", "DSS14-Hold-v0"], args.steps, args.repeats)
    for env_id, r in rates.items():
        print(f"{env_id:15s} single env: {r:12,.0f} steps/s", flush=True)
    for env_id in ("DSS14-v0", "DSS14-Hold-v0"):
        print(f"{env_id:15s} ratio to Pendulum-v1: {rates[env_id] / rates['Pendulum-v1']:.2f}x (target >= 2)")
    for env_id in ("DSS14-v0", "DSS14-Hold-v0"):
        r = vector_env_rate(env_id, args.num_envs, args.vec_steps, args.repeats)
        print(f"{env_id:15s} vector env N={args.num_envs}: {r:12,.0f} env-steps/s (target >= 2,000,000)",
              flush=True)


if __name__ == "__main__":
    main()
