"""Command-line interface: ``dss14 <subcommand>``."""

from __future__ import annotations

import argparse
import sys
import time


def _reproduce(args: argparse.Namespace) -> int:
    """Write everything, then exit 1 when a row with an accepted range is outside it."""
    from dss14_env.core.outdir import prepare_output_dir
    from dss14_env.model.assembly import build_model, default_model
    from dss14_env.model.config import load_model_config
    from dss14_env.reproduce import OWNED_FILES, reproduce

    t0 = time.perf_counter()
    cfg = load_model_config(args.config) if args.config else None  # bad config: before any work
    prepare_output_dir(args.out, OWNED_FILES, overwrite=args.overwrite)
    model = build_model(cfg) if cfg is not None else default_model()
    res = reproduce(args.out, model, figures=not args.no_figures)
    print(res["markdown"])
    print(f"{len(res['figures'])} figures, metrics.json and metrics.md written to {args.out} "
          f"in {time.perf_counter() - t0:.1f} s")
    bad = res["failed"]
    if bad:
        rows = res["metrics"]
        for k in bad:
            lo, hi = rows[k]["accepted"]
            print(f"dss14 reproduce: {k} = {rows[k]['model']:.4g} is outside the accepted range "
                  f"[{lo:.4g}, {hi:.4g}]", file=sys.stderr)
        print(f"dss14 reproduce: {len(bad)} row(s) outside the accepted range: {', '.join(bad)}",
              file=sys.stderr)
        return 1
    print("every row with an accepted range is inside it")
    return 0


def _train(args: argparse.Namespace) -> int:
    from dss14_env.agents.campaign import parse_seeds, train_seeds
    from dss14_env.agents.train import TrainingInterrupted, config_for_command, train

    cfg = config_for_command(args.algo, args.config, args.env, args.resume, args.timesteps,
                             args.seed)
    try:
        if args.seeds is not None:
            if args.resume is not None or args.seed is not None:
                raise ValueError("--seeds trains fresh runs: without --resume and --seed")
            if args.out is None:
                raise ValueError("--seeds needs --out (the campaign folder)")
            out = train_seeds(cfg, parse_seeds(args.seeds), args.out, overwrite=args.overwrite)
            print(f"{len(parse_seeds(args.seeds))} runs, summary.json and learning curves "
                  f"written to {out}")
            return 0
        run = train(cfg, run_dir=args.out, resume=args.resume, overwrite=args.overwrite,
                    trust_pickle=args.trust_pickle)
    except TrainingInterrupted as exc:
        print(f"dss14 train: {exc.message}", file=sys.stderr)
        return 130
    print(f"{cfg.algo} run written to {run} (policy folder: policy.pt, normalization.npz, "
          f"config.yaml)")
    return 0


def _bench(args: argparse.Namespace) -> int:
    import shlex

    from dss14_env.bench.bench import bench, build_plan

    cmd = "dss14 " + shlex.join(args.argv)
    plan = build_plan(controllers=args.controllers, scenarios=args.scenarios, seeds=args.seeds,
                      wind_speeds=args.wind_speeds, steps=args.steps, quick=args.quick,
                      ppo_model=args.ppo_model, randomize=args.randomize, out=args.out,
                      figures=not args.no_figures, sweep=not args.no_sweep,
                      sweep_seeds=args.sweep_seeds, command=cmd)
    for note in plan.notes:
        print(f"dss14 bench: warning: {note}", file=sys.stderr)
    print(plan.describe(), flush=True)
    res = bench(plan, progress=not args.no_progress)
    print(res["main_table"])
    print(f"results.json, results.md and {len(res['figures'])} figures written to {plan.out} "
          f"in {res['wall_time_s']:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``dss14`` console script."""
    parser = argparse.ArgumentParser(prog="dss14", description="DSS-14 antenna servo model and tools")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("reproduce", help="redraw the report's figures and check its numbers")
    p.add_argument("--out", default="reproduce_out", help="output folder (default: reproduce_out)")
    p.add_argument("--config", default=None,
                   help="model YAML, a path or a shipped name (default: the shipped configs/model.yaml)")
    p.add_argument("--no-figures", action="store_true", help="metrics only")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of an earlier run in --out (metrics, figures)")
    p.set_defaults(func=_reproduce)
    p = sub.add_parser("train", help="train a learned controller (PPO, RecurrentPPO, SAC)",
                       description="Train one run (or one per seed with --seeds) into a run "
                       "folder (docs/rl.md).")
    p.add_argument("algo", choices=["ppo", "recurrent_ppo", "sac"], help="algorithm")
    p.add_argument("--config", default=None, metavar="NAME|FILE",
                   help="training YAML, or a shipped config's name (ppo, ppo_plain, ppo_smoke, "
                   "sac, recurrent_ppo); default: configs/<algo>.yaml, on --resume the run's")
    p.add_argument("--env", default=None, metavar="ID",
                   help="take the shipped hyperparameters of this environment id "
                   "(configs/hyperparams/<algo>.yml) instead of --config")
    p.add_argument("--out", default=None,
                   help="run folder (default: runs/<algo>-<timestamp>/); with --seeds the "
                   "campaign folder")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run files already in --out (a finished or interrupted run)")
    p.add_argument("--resume", default=None, metavar="CHECKPOINT",
                   help="checkpoint folder (<run>/checkpoints/<N>_steps) to continue from")
    p.add_argument("--trust-pickle", action="store_true",
                   help="allow --resume from a stable-baselines3 .zip (unpickled: it can run "
                   "code; only for files you trust)")
    p.add_argument("--timesteps", type=int, default=None, help="override total_timesteps")
    p.add_argument("--seed", type=int, default=None, help="override seed")
    p.add_argument("--seeds", nargs="+", default=None, metavar="K",
                   help="one run per seed index into --out/seed_<k>/ (0-4, or 0 3 7), then "
                   "summary.json and learning curves")
    p.set_defaults(func=_train)
    p = sub.add_parser("bench", help="score PI, LQG, MPC and PPO on the same scenarios and seeds",
                       description="Run every controller through the runner on the same "
                       "scenarios and seeds; write results.json, results.md and PNG figures "
                       "(docs/bench.md).")
    p.add_argument("--quick", action="store_true",
                   help="short version: 1 seed, shorter episodes, wind speeds 30 50 70 (under a minute)")
    p.add_argument("--seeds", nargs="+", metavar="SEED", default=None,
                   help="one value N: seeds 0..N-1; several: those seeds (default: 0 1)")
    p.add_argument("--controllers", nargs="+", metavar="NAME", default=None,
                   help="pi_kp1 pi_kp0.7 lqg mpc ppo yardstick (default: all but yardstick)")
    p.add_argument("--scenarios", nargs="+", metavar="NAME", default=None,
                   help="hold_front hold_side step track slew (default: all)")
    p.add_argument("--wind-speeds", nargs="+", metavar="KMH", default=None,
                   help="speeds of the error-vs-wind sweep, km/h (default: 30 40 50 60 70)")
    p.add_argument("--no-sweep", action="store_true", help="skip the error-vs-wind sweep")
    p.add_argument("--sweep-seeds", type=int, default=None, metavar="N",
                   help="run the sweep on the first N seeds (default 1)")
    p.add_argument("--steps", type=int, default=None,
                   help="episode length of every scenario and sweep point, control periods "
                   "(default: the scenario's; 50 per second)")
    p.add_argument("--ppo-model", default=None, metavar="PATH",
                   help="PPO run folder, eval/best folder or zip (default: the shipped policy)")
    p.add_argument("--randomize", action="store_true",
                   help="randomised plant parameters every episode (randomize_params=True)")
    p.add_argument("--out", default="bench_out", help="output folder (default: bench_out)")
    p.add_argument("--no-figures", action="store_true", help="results.json and results.md only")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_bench)
    args = parser.parse_args(argv)
    args.argv = list(argv) if argv is not None else sys.argv[1:]
    return run_command(args)


def run_command(args: argparse.Namespace) -> int:
    """Run a parsed subcommand; every expected failure becomes one line on stderr.

    Bad input (configuration, options, files) and operating-system errors (a folder that cannot
    be written, a full disk) exit with status 2, an interruption (Ctrl-C) with 130; a bug still
    shows its traceback.
    """
    try:
        return args.func(args)
    except (ValueError, KeyError, RuntimeError, OSError) as exc:
        print(f"dss14 {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"dss14 {args.command}: interrupted", file=sys.stderr)
        return 130


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line (an OSError names its file)."""
    if isinstance(exc, OSError) and exc.filename is not None:
        msg = f"{exc.filename}: {exc.strerror or exc}"
    elif isinstance(exc, KeyError) and exc.args:
        msg = str(exc.args[0])
    else:
        msg = str(exc) or type(exc).__name__
    return " ".join(msg.split())


if __name__ == "__main__":
    sys.exit(main())
