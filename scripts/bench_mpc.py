"""Time the MPC controller per step: ``act()`` wall time (ms), per scenario, with 95 % intervals.

Run on two cores, as the target is stated::

    taskset -c 0,1 python scripts/bench_mpc.py --json docs/results/mpc_timing.json
    taskset -c 0,1 python scripts/bench_mpc.py --controller mpc_pointing \
        --json docs/results/mpc_pointing_timing.json

``--controller`` picks the MPC: ``mpc`` (default, the encoder design) or ``mpc_pointing`` (the
MPC on the dish's pointing outputs, :class:`dss14_env.baselines.mpc.PointingMPCController`).

Each scenario runs ``--seeds`` episodes of ``--steps`` steps (one controller, reset per episode;
its first step, which selects the design and canonicalises the problem, is left out).  The
per-step times of one episode are correlated, so the unit of the statistics is the episode: the
figure is the median over episodes of each episode's median ``act()`` time, with a percentile
bootstrap 95 % interval over the episodes (:func:`dss14_env.core.stats.bootstrap_ci`).  With
``--compare`` the same episodes (first ``--compare-steps`` steps) also run with the fast path
off (``Problem.solve`` every step) and the speed-up is a paired ratio with its interval
(:func:`dss14_env.core.stats.ratio_ci`).  Target: median <= 1.5 ms per step, met when the
interval's upper end is below it.  Prints one line per scenario and a verdict; ``--json`` also
writes everything (machine, versions, options, per-episode values); the exit status is 1 when
the target is missed.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from importlib import metadata

import numpy as np

from dss14_env.baselines.mpc import MPCController, PointingMPCController
from dss14_env.bench.runner import SCENARIOS
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.stats import bootstrap_ci, ratio_ci
from dss14_env.envs.env import DSS14Env

#: median act() time per step the MPC must stay under, ms
TARGET_MEDIAN_MS = 1.5
#: the MPCs this script times, by catalog name
MPC_CLASSES = {"mpc": MPCController, "mpc_pointing": PointingMPCController}


def episode_times(ctrl: MPCController, env: DSS14Env, seed: int, steps: int) -> dict:
    """``act()`` times (ms) of one episode after its first step, and its solver record."""
    obs, _ = env.reset(seed=seed)
    ctrl.reset(seed)
    obs, *_ = env.step(ctrl.act(obs))  # first step: design selection, problem canonicalisation
    times, solver = [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        a = ctrl.act(obs)
        times.append(time.perf_counter() - t0)
        solver.append(ctrl.info["mpc_solve_time_s"])
        obs, _, terminated, _, _ = env.step(a)
        if terminated:
            break
    t = np.array(times) * 1e3
    return {"seed": seed, "steps": int(t.size), "median_ms": float(np.median(t)),
            "p95_ms": float(np.percentile(t, 95)), "max_ms": float(t.max()),
            "solver_median_ms": float(np.median(solver) * 1e3),
            "fallbacks": ctrl.info["fallbacks"], "resolves": ctrl.info["resolves"]}


def bench(scenario: str, steps: int, seeds: list[int], compare_steps: int,
          controller: str = "mpc") -> dict:
    """Time the MPC ``controller`` (a key of :data:`MPC_CLASSES`) on one runner scenario (see the
    module docstring).
    """
    cls = MPC_CLASSES[controller]
    env = DSS14Env(**SCENARIOS[scenario].env)
    fast = cls(env)
    eps = [episode_times(fast, env, s, steps) for s in seeds]
    med = np.array([e["median_ms"] for e in eps])
    out = {"scenario": scenario, "episodes": eps,
           "median_ms": bootstrap_ci(med, np.median, np.random.default_rng(0)).as_dict(),
           "p95_ms_median": float(np.median([e["p95_ms"] for e in eps])),
           "n_fallbacks": int(sum(len(e["fallbacks"]) for e in eps)),
           "n_resolves": int(sum(len(e["resolves"]) for e in eps))}
    if compare_steps:
        slow = cls(env, fast=False)
        slow_eps = [episode_times(slow, env, s, compare_steps) for s in seeds]
        fast_short = [episode_times(fast, env, s, compare_steps) for s in seeds]
        out["problem_solve_median_ms"] = bootstrap_ci([e["median_ms"] for e in slow_eps], np.median,
                                                      np.random.default_rng(0)).as_dict()
        out["speedup_vs_problem_solve"] = ratio_ci(
            [e["median_ms"] for e in slow_eps], [e["median_ms"] for e in fast_short], np.median,
            np.random.default_rng(1), paired=True).as_dict()
        out["compare_steps"] = compare_steps
    return out


def machine() -> dict:
    """What the figures were measured on."""
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), cpu)
    except OSError:
        pass
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    versions = {}
    for pkg in ("numpy", "scipy", "cvxpy", "osqp", "dss14-env"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    return {"cpu": cpu, "cpus_available": cpus, "cpu_count": os.cpu_count(),
            "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            "python": platform.python_version(), "platform": platform.platform(), "versions": versions}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1500, help="timed steps per episode (default 1500)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4],
                   help="episode seeds, the statistical units (default 0 1 2 3 4)")
    p.add_argument("--scenarios", nargs="+", default=["hold_front", "hold_side", "step", "slew", "track"],
                   choices=sorted(SCENARIOS), help="runner scenarios (default: all five)")
    p.add_argument("--compare", action="store_true", help="also time Problem.solve every step")
    p.add_argument("--compare-steps", type=int, default=300, help="steps per episode of --compare")
    p.add_argument("--json", metavar="FILE", help="write the results to this JSON file")
    p.add_argument("--controller", default="mpc", choices=sorted(MPC_CLASSES),
                   help="the MPC to time (default mpc)")
    args = p.parse_args(argv)
    if args.steps < 10 or args.compare_steps < 10:
        p.error("--steps and --compare-steps must be at least 10")
    if args.json and not os.path.isdir(os.path.dirname(os.path.abspath(args.json))):
        p.error(f"--json: folder of {args.json!r} does not exist")
    info = machine()
    print(f"CPU {info['cpu']}; CPUs available {info['cpus_available']} (target stated for 2 cores: "
          f"taskset -c 0,1); {info['versions']}")
    t0 = time.perf_counter()
    results, ok = [], True
    for sc in args.scenarios:
        r = bench(sc, args.steps, list(args.seeds), args.compare_steps if args.compare else 0,
                  args.controller)
        m = r["median_ms"]
        good = m["ci95"][1] <= TARGET_MEDIAN_MS and r["n_fallbacks"] == 0
        ok &= good
        line = (f"{sc:>11s}: median {m['value']:.2f} ms [95 % CI {m['ci95'][0]:.2f}, {m['ci95'][1]:.2f}] "
                f"over {m['n']} episodes x {args.steps} steps, p95 {r['p95_ms_median']:.2f} ms, "
                f"fallbacks {r['n_fallbacks']}, re-solves {r['n_resolves']}")
        if args.compare:
            s, q = r["problem_solve_median_ms"], r["speedup_vs_problem_solve"]
            line += (f"; Problem.solve {s['value']:.2f} ms, speed-up {q['value']:.1f}x "
                     f"[{q['ci95'][0]:.1f}, {q['ci95'][1]:.1f}]")
        print(line + ("  OK" if good else "  MISSED"))
        results.append(r)
    verdict = "met" if ok else "MISSED"
    print(f"target median <= {TARGET_MEDIAN_MS} ms per step (upper end of the 95 % CI), "
          f"no fallbacks: {verdict}")
    if args.json:
        doc = {"what": f"{MPC_CLASSES[args.controller].__name__}.act() wall time per step "
                       "(scripts/bench_mpc.py)", "controller": args.controller,
               "target_median_ms": TARGET_MEDIAN_MS, "target_met": bool(ok),
               "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
               "machine": info, "options": vars(args), "wall_time_s": time.perf_counter() - t0,
               "scenarios": results}
        atomic_write_text(args.json, json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
