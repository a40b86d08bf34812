"""Speed of the DSS14 environments: single-env steps/s against Pendulum-v1, the batched vector
env's env-steps/s against the raw matrix product its step is built on, and the environment's
share of a PPO training's time; with the compiled step's compile time on first use.

Run it from the repository (it imports the repository's ``dss14_env``)::

    python scripts/bench_env_speed.py                                   # print
    python scripts/bench_env_speed.py --json docs/results/env_speed.json  # and keep the results

How it measures.  The single environments are made with ``gymnasium.make`` (so all carry the
same standard wrappers) and stepped with actions drawn beforehand (uniform over the action
space); an episode end triggers a reset, which is counted in the time.  In each of
``--repeats`` rounds every environment makes ``--steps`` steps, the environments taking turns
every 1 000 steps (in reverse order every other round), so that a change of the machine's load
affects them alike; the ratio
to Pendulum-v1 is taken per round (same load) and summarised by its median over the rounds with
a 95 % bootstrap interval over the rounds (:func:`dss14_env.core.stats.bootstrap_ci`).  The
vector env's rate is summarised the same way over its repeats -- each of ``--vec-steps`` steps,
by default one episode length of the registration (``max_episode_steps``), so that every repeat
holds the same share of autoresets (all sub-environments start together and are truncated
together: with shorter repeats, the repeats that hold the autoreset are the slow ones) -- and
set against the **raw
matmul** of its plant size measured in the same repeat (same load): ``(N x K) @ (K x n+4)``,
the plant's batch step map (``Plant.vector_step_matrix``: ``Plant.batch_step_matrix``
restricted to the state and the step outputs, the map the vector env steps with) into a
preallocated output, rows per second -- the
limit of a step that is one such product plus per-row work; the ratio is taken per repeat.
The **PPO env share**: SB3's PPO (the shipped recipe's sizes: 8 environments from
``stable_baselines3.common.env_util.make_vec_env`` over ``gymnasium.make`` -- a
``DummyVecEnv`` --, 1 024 steps per environment per rollout, minibatches of 512, 10 epochs, a
64-64 MLP, on the CPU) learns ``--ppo-steps`` steps in each of ``--ppo-repeats`` runs; the
share is the time spent inside the vector env's ``reset`` and ``step_wait`` (every
environment's step, its wrappers and autoresets) over the time of ``model.learn``, both on the
wall clock whatever ``--clock`` (torch's threads would count several times on the CPU clock).
The **compile time** is measured in a fresh process: the first reset and step of ``DSS14-v0``
(which compile the step's loops) less the second ones (the plants then kept).
``--check`` exits with status 1 when a figure misses its target (single env >= 1.5x
Pendulum-v1, vector env >= 0.5x the raw matmul, PPO env share <= 15 %), judged on the far end
of its interval.
``--clock cpu`` times with the process's CPU time instead of the wall clock: on a machine
shared with other jobs it is much less disturbed (the single environments are
single-threaded; the vector env's BLAS threads are counted too -- OpenBLAS threads spin while
they wait, so with several BLAS threads on a busy machine its CPU-time rate says little: use
``--blas-threads 1`` with ``--clock cpu``).  The result file records the clock, the settings,
the machine (CPU count, load average) and the package versions with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
import dss14_env  # noqa: E402,F401  (registers DSS14-v0)
from dss14_env.core.outdir import atomic_write_text  # noqa: E402
from dss14_env.core.stats import bootstrap_ci  # noqa: E402

SINGLE_IDS = ("Pendulum-v1", "DSS14-v0", "DSS14-Hold-v0")
VECTOR_IDS = ("DSS14-v0", "DSS14-Hold-v0")
TARGET_RATIO = 1.5
#: the vector env's target: at least this share of the raw matmul rate of its plant size
TARGET_MATMUL_SHARE = 0.5
#: the PPO env share's target: at most this share of the training time in the environment
TARGET_ENV_SHARE = 0.15
#: the PPO run's sizes (the shipped recipe's, configs/ppo.yaml)
PPO_ENVS, PPO_N_STEPS, PPO_BATCH, PPO_EPOCHS = 8, 1024, 512, 10
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
#: single-env steps each environment runs before the next takes its turn, within a round
SINGLE_CHUNK = 1000


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

    def seconds(self, clock, start: int, stop: int) -> float:
        """Seconds of the steps ``start:stop`` of the actions (episode ends reset, inside the
        timing).
        """
        env, actions = self.env, self.actions[start:stop]
        t0 = clock()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        return clock() - t0


def single_env_rates(env_ids: tuple[str, ...], n_steps: int, repeats: int, clock,
                     chunk: int = SINGLE_CHUNK) -> dict[str, list[float]]:
    """Steps/s of each environment per round (one pass over its ``n_steps`` actions); within a
    round the ids take turns every ``chunk`` steps, so that the rates of a round are measured
    under the same load, in the order given in even rounds and reversed in odd ones (an
    environment runs a little slower right after another one's code ran: each follows each
    other equally often).
    """
    runs = {env_id: _SingleRun(env_id, n_steps) for env_id in env_ids}
    rates: dict[str, list[float]] = {env_id: [] for env_id in env_ids}
    for r in range(repeats):
        seconds = dict.fromkeys(env_ids, 0.0)
        order = env_ids if r % 2 == 0 else env_ids[::-1]
        for start in range(0, n_steps, chunk):
            for env_id in order:
                seconds[env_id] += runs[env_id].seconds(clock, start, min(start + chunk, n_steps))
        for env_id in env_ids:
            rates[env_id].append(n_steps / seconds[env_id])
    return rates


def plant_product(envs, num_envs: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The operands of the vector env's plant step for ``num_envs`` rows: random rows ``Z``
    (N x K), the plant's step map ``M`` (K x n+4) and the output (N x n+4).
    """
    base = envs.unwrapped if hasattr(envs, "unwrapped") else envs
    M = base.plants.plant(0.0, base.config.dt).vector_step_matrix  # the sizes of every plant of the env
    Z = np.random.default_rng(seed).standard_normal((num_envs, M.shape[0]))
    return Z, M, np.empty((num_envs, M.shape[1]))


def vector_env_rates(env_id: str, num_envs: int, n_steps: int | None, repeats: int, clock,
                     seed: int = 0) -> tuple[list[float], list[float], list[int], int, bool]:
    """Env-steps/s of the ``vector_entry_point`` vector env and rows/s of the raw matmul of
    its plant size (:func:`plant_product`), measured back to back in every repeat of ``n_steps``
    steps (None: the registration's episode length), the product's shape ``[N, K, n+4]``, the
    steps per repeat and whether the env's step ran compiled (``DSS14VectorEnv.compiled``).
    """
    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    compiled = bool(getattr(envs.unwrapped, "compiled", False))
    if n_steps is None:  # one episode length: every repeat holds one autoreset of all
        n_steps = gym.spec(env_id).max_episode_steps or 1000
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-0.01, 0.01, (64, num_envs, 2)).astype(np.float32)
    envs.reset(seed=seed)
    for i in range(20):
        envs.step(actions[i % 64])
    Z, M, out = plant_product(envs, num_envs, seed)
    rates, raw = [], []
    for _ in range(repeats):
        t0 = clock()
        for i in range(n_steps):
            envs.step(actions[i % 64])
        rates.append(num_envs * n_steps / (clock() - t0))
        t0 = clock()
        for _ in range(n_steps):
            np.matmul(Z, M, out=out)
        raw.append(num_envs * n_steps / (clock() - t0))
    envs.close()
    return rates, raw, [num_envs, M.shape[0], M.shape[1]], n_steps, compiled


class _Timer:
    """Adds up the time spent in the functions it wraps."""

    def __init__(self, clock) -> None:
        self.clock, self.spent = clock, 0.0

    def wrap(self, f):
        def run(*args, **kwargs):
            t0 = self.clock()
            try:
                return f(*args, **kwargs)
            finally:
                self.spent += self.clock() - t0
        return run


def ppo_env_shares(env_id: str, total_steps: int, repeats: int, clock, seed: int = 0) -> list[float]:
    """The share of ``model.learn``'s time spent in the environment (the vector env's ``reset``
    and ``step_wait``), one per run of SB3's PPO over ``make_vec_env`` (see the module docstring).
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    shares = []
    for r in range(repeats):
        venv = make_vec_env(env_id, n_envs=PPO_ENVS, seed=seed + r)
        timer = _Timer(clock)
        venv.reset, venv.step_wait = timer.wrap(venv.reset), timer.wrap(venv.step_wait)
        torch.manual_seed(seed + r)
        model = PPO("MlpPolicy", venv, n_steps=PPO_N_STEPS, batch_size=PPO_BATCH, n_epochs=PPO_EPOCHS,
                    policy_kwargs={"net_arch": [64, 64]}, device="cpu", seed=seed + r, verbose=0)
        t0 = clock()
        model.learn(total_timesteps=total_steps)
        shares.append(timer.spent / (clock() - t0))
        venv.close()
    return shares


_FIRST_STEP = """
import time, numpy as np, gymnasium as gym, dss14_env
env = gym.make("DSS14-v0")
t = []
for _ in range(2):
    t0 = time.perf_counter()
    env.reset(seed=0)
    env.step(np.zeros(2, np.float32))
    t.append(time.perf_counter() - t0)
print(t[0] - t[1])
"""


def compile_seconds() -> float:
    """Seconds the step's loops take to compile on first use, in a fresh process (the first
    reset and step of ``DSS14-v0`` less the second).
    """
    # away from the source tree: the package the script measures is the installed one
    done = subprocess.run([sys.executable, "-c", _FIRST_STEP], capture_output=True, text=True, timeout=300,
                          check=True, cwd=tempfile.gettempdir())
    return float(done.stdout.split()[-1])


def summary(values: list[float]) -> dict:
    """Median with its 95 % bootstrap interval over the rounds, the best and every value."""
    v = np.asarray(values, float)
    ci = bootstrap_ci(v, np.median, rng=np.random.default_rng(0)) if v.size >= 3 else None
    return {"median": float(np.median(v)), "ci95": None if ci is None else [ci.low, ci.high],
            "best": float(v.max()), "values": v.tolist(), "n": int(v.size)}


def run(args: argparse.Namespace) -> dict:
    """Measure everything; the results as a JSON-ready dict."""
    clock = CLOCKS[args.clock]
    rates = single_env_rates(SINGLE_IDS, args.steps, args.repeats, clock)
    out: dict = {"single": {}, "ratio_to_pendulum": {}, "vector": {}, "matmul": {}, "ratio_to_matmul": {}}
    for env_id, r in rates.items():
        out["single"][env_id] = summary(r)
    pend = np.asarray(rates["Pendulum-v1"])
    for env_id in SINGLE_IDS[1:]:
        ratios = np.asarray(rates[env_id]) / pend  # per round: the same load on both
        s = summary(ratios.tolist())
        s["target"] = TARGET_RATIO
        s["meets_target"] = None if s["ci95"] is None else bool(s["ci95"][0] >= TARGET_RATIO)
        out["ratio_to_pendulum"][env_id] = s
    with threadpool_limits(limits=args.blas_threads, user_api="blas"):
        for env_id in VECTOR_IDS:
            vec, raw, shape, n_steps, compiled = vector_env_rates(env_id, args.num_envs, args.vec_steps,
                                                                  args.repeats, clock)
            out["vector"][env_id] = {**summary(vec), "steps_per_repeat": n_steps, "compiled": compiled}
            out["matmul"][env_id] = {**summary(raw), "shape": shape}
            s = summary((np.asarray(vec) / np.asarray(raw)).tolist())  # per repeat: the same load
            s["target"] = TARGET_MATMUL_SHARE
            s["meets_target"] = None if s["ci95"] is None else bool(s["ci95"][0] >= TARGET_MATMUL_SHARE)
            out["ratio_to_matmul"][env_id] = s
    if args.ppo_steps:
        s = summary(ppo_env_shares("DSS14-v0", args.ppo_steps, args.ppo_repeats, CLOCKS["wall"]))
        s["target"] = TARGET_ENV_SHARE
        s["meets_target"] = None if s["ci95"] is None else bool(s["ci95"][1] <= TARGET_ENV_SHARE)
        out["ppo_env_share"] = {"DSS14-v0": s}
    out["compile_s"] = compile_seconds()
    out["settings"] = {"clock": args.clock, "steps": args.steps, "vec_steps": args.vec_steps,
                       "num_envs": args.num_envs, "repeats": args.repeats, "blas_threads": args.blas_threads,
                       "ppo_steps": args.ppo_steps, "ppo_repeats": args.ppo_repeats}
    out["machine"] = {"cpus": os.cpu_count(), "load_average_1_5_15": list(os.getloadavg()),
                      "platform": platform.platform(), "python": platform.python_version(),
                      "numpy": np.__version__, "gymnasium": gym.__version__,
                      "dss14_env": dss14_env.__version__, "git_revision": _git_revision()}
    out["when"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    return out


def _git_revision() -> str | None:
    """The repository's commit (with ``-dirty`` for uncommitted changes), None outside git."""
    try:
        rev = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return rev or None


def _fmt_ci(s: dict, fmt: str) -> str:
    if s["ci95"] is None:
        return ""
    return f" (95 % CI {format(s['ci95'][0], fmt)} - {format(s['ci95'][1], fmt)})"


def report(res: dict) -> str:
    """The results as text lines."""
    st, m = res["settings"], res["machine"]
    lines = [f"clock: {st['clock']}, {st['repeats']} rounds, BLAS threads of the vector env: "
             f"{st.get('blas_threads') or 'as is'}, load average {m['load_average_1_5_15'][0]:.1f} on "
             f"{m['cpus']} CPUs"]
    for env_id, s in res["single"].items():
        lines.append(f"{env_id:15s} single env: median {s['median']:12,.0f} steps/s{_fmt_ci(s, ',.0f')}, "
                     f"best {s['best']:,.0f}")
    for env_id, s in res["ratio_to_pendulum"].items():
        verdict = {True: "meets", False: "does not meet (CI reaches below)", None: "too few rounds for"}[
            s["meets_target"]]
        lines.append(f"{env_id:15s} ratio to Pendulum-v1: median {s['median']:.2f}x{_fmt_ci(s, '.2f')}, "
                     f"best-round {s['best']:.2f}x; {verdict} the target >= {s['target']:g}")
    for env_id, s in res["vector"].items():
        lines.append(f"{env_id:15s} vector env N={res['settings']['num_envs']}: median {s['median']:12,.0f} "
                     f"env-steps/s{_fmt_ci(s, ',.0f')}, best {s['best']:,.0f}")
    for env_id, s in res.get("ratio_to_matmul", {}).items():
        mm = res["matmul"][env_id]
        n, k, m = mm["shape"]
        verdict = {True: "meets", False: "does not meet (CI reaches below)", None: "too few rounds for"}[
            s["meets_target"]]
        lines.append(f"{env_id:15s} raw matmul ({n}x{k})@({k}x{m}): median {mm['median']:12,.0f} rows/s; "
                     f"vector env / matmul: median {s['median']:.2f}x{_fmt_ci(s, '.2f')}; {verdict} the "
                     f"target >= {s['target']:g}")
    for env_id, s in res.get("ppo_env_share", {}).items():
        verdict = {True: "meets", False: "does not meet (CI reaches above)", None: "too few runs for"}[
            s["meets_target"]]
        lines.append(f"{env_id:15s} PPO env share: median {s['median']:.1%}{_fmt_ci(s, '.1%')} over "
                     f"{s['n']} runs of {res['settings']['ppo_steps']:,} steps; {verdict} the target "
                     f"<= {s['target']:.0%}")
    lines.append(f"compile time of the step's loops on first use: {res['compile_s']:.1f} s")
    return "\n".join(lines)


def misses(res: dict) -> list[str]:
    """The ratios whose interval reaches below their target (or that have no interval)."""
    return [f"{kind} {env_id}" for kind in ("ratio_to_pendulum", "ratio_to_matmul", "ppo_env_share")
            for env_id, s in res.get(kind, {}).items() if not s["meets_target"]]


def main() -> int:
    """Print the rates and the ratios to Pendulum-v1 and to the raw matmul; ``--json`` keeps
    them; ``--check``: status 1 when a ratio misses its target.
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=30000, help="single-env steps per round")
    ap.add_argument("--vec-steps", type=int, default=None,
                    help="vector-env steps per repeat (default: the registration's episode length)")
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=16, help="rounds (at least 3 for an interval)")
    ap.add_argument("--clock", choices=sorted(CLOCKS), default="wall")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="limit the BLAS threads of the vector env's matrix products (default: as is)")
    ap.add_argument("--ppo-steps", type=int, default=16384,
                    help="PPO steps per run for the env share (0: not measured)")
    ap.add_argument("--ppo-repeats", type=int, default=3, help="PPO runs (at least 3 for an interval)")
    ap.add_argument("--json", type=Path, default=None, help="write the results to this JSON file")
    ap.add_argument("--check", action="store_true",
                    help="exit with status 1 when a ratio misses its target (the CI's lower end)")
    args = ap.parse_args()
    if args.repeats < 1 or args.steps < 1 or (args.vec_steps is not None and args.vec_steps < 1) or (
            args.num_envs < 1) or (
            args.blas_threads is not None and args.blas_threads < 1) or args.ppo_steps < 0 or (
            args.ppo_repeats < 1):
        ap.error("--repeats, --steps, --vec-steps, --num-envs, --blas-threads and --ppo-repeats must be "
                 "positive, --ppo-steps non-negative")
    if args.json is not None and not (args.json.parent.is_dir() and os.access(args.json.parent, os.W_OK)):
        ap.error(f"--json: folder {args.json.parent} does not exist or is not writable")
    if args.json is not None and args.json.is_dir():
        ap.error(f"--json: {args.json} is a folder")
    res = run(args)
    print(report(res), flush=True)
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(res, indent=2) + "\n")
    missed = misses(res)
    if args.check and missed:
        print(f"targets missed: {', '.join(missed)}", flush=True)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
