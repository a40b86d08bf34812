"""Command-line interface: ``dss14 <subcommand>``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from dss14_env.agents.config import shipped_training_configs_by_algo
from dss14_env.bench import catalog
from dss14_env.bench.plan import QUICK_WIND_SPEEDS_KMH
from dss14_env.core.text import counted
from dss14_env.model.variants import DRIVE_VARIANTS


def _reproduce(args: argparse.Namespace) -> int:
    """Write everything, then exit 1 when a row with an accepted range is outside it."""
    from dss14_env.core.outdir import manifest_kept, prepare_output_dir
    from dss14_env.model.assembly import build_model, default_model
    from dss14_env.model.config import load_model_config
    from dss14_env.reproduce import OWNED_FILES, reproduce

    t0 = time.perf_counter()
    cfg = load_model_config(args.config) if args.config else None  # bad config: before any work
    prepare_output_dir(args.out, OWNED_FILES, overwrite=args.overwrite)
    with manifest_kept(args.out):
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


#: ``--resume`` given without a checkpoint: continue the run or campaign in ``--out``
LATEST = "<latest>"


def _train_resume(args: argparse.Namespace) -> tuple[str | None, bool]:
    """``(checkpoint to resume a single run from, or None; whether a --seeds campaign is
    continued)`` from ``--resume [CHECKPOINT]`` and its alias ``--continue``.
    """
    from dss14_env.agents.train import last_checkpoint

    resume = LATEST if args.continue_ and args.resume is None else args.resume
    if args.seeds is not None:
        if resume not in (None, LATEST):
            raise ValueError("--resume: with --seeds it continues the campaign in --out and takes "
                             "no checkpoint (--seeds ... --out DIR --resume)")
        return None, resume == LATEST
    if resume != LATEST:
        return resume, False
    if args.out is None:
        raise ValueError("--resume without a checkpoint continues the run in --out: give --out, "
                         "or --resume <run>/checkpoints/<N>_steps")
    last = last_checkpoint(Path(args.out))
    if last is None:
        raise ValueError(f"--resume: {args.out} holds no checkpoint to continue from (a run "
                         f"stopped before its first checkpoint starts again with --overwrite)")
    return str(last), False


def campaign_resume_command(args: argparse.Namespace) -> str:
    """The one command that continues an interrupted ``dss14 train --seeds`` campaign."""
    import shlex

    cmd = ["dss14", "train", args.algo, "--config", str(Path(args.out) / "config.yaml"),
           "--seeds", *args.seeds, "--out", str(args.out), "--resume"]
    if args.env_module:
        cmd += ["--env-module", args.env_module]
    if args.address is not None:
        cmd += ["--address", args.address]
    elif args.num_cpus is not None:
        cmd += ["--num-cpus", str(args.num_cpus)]
    elif args.ray:
        cmd += ["--ray"]
    return shlex.join(cmd)


def _train(args: argparse.Namespace) -> int:
    from dss14_env.agents.campaign import owned_files, parse_seeds, train_seeds
    from dss14_env.agents.sweep import train_sweep
    from dss14_env.agents.train import TrainingInterrupted, config_for_command, train
    from dss14_env.core.outdir import prepare_output_dir
    from dss14_env.core.parallel import check_ray_options, make_executor, probe_address, require_ray

    use_ray = args.ray or args.address is not None or args.num_cpus is not None
    resume, resume_campaign = _train_resume(args)
    cfg = config_for_command(args.algo, args.config, args.env, resume, args.timesteps,
                             args.seed, args.env_module)
    if cfg.sweep and (args.seeds is None or args.out is None):
        raise ValueError(f"{cfg.source}: field 'sweep': a sweep trains one campaign per point: "
                         f"give --seeds (e.g. 0-4) and --out")
    if use_ray:  # before Ray starts: bad options, an unusable --out, or no Ray (how to install it)
        if args.seeds is None or args.out is None:
            raise ValueError("--ray runs the runs of --seeds as Ray tasks: give --seeds and --out")
        parse_seeds(args.seeds)
        check_ray_options(args.address, args.num_cpus)
        require_ray()
        probe_address(args.address)
        if not resume_campaign:  # checked only: nothing removed before the runs are checked
            prepare_output_dir(args.out, owned_files(args.out), args.overwrite, dry_run=True)
    if args.seeds is None:
        if args.continue_:
            raise ValueError("--continue continues a campaign: give --seeds and --out")
        try:
            progress = args.progress if args.progress is not None else (True if sys.stderr.isatty() else None)
            run = train(cfg, run_dir=args.out, resume=resume, overwrite=args.overwrite,
                        trust_pickle=args.trust_pickle, progress=progress)
        except TrainingInterrupted as exc:
            print(f"dss14 train: {exc.message}", file=sys.stderr)
            return 130
        print(f"{cfg.algo} run written to {run} (policy folder: policy.pt, normalization.npz, "
              f"config.yaml)")
        return 0
    if args.seed is not None:
        raise ValueError("--seeds trains one run per seed index: without --seed (the config's "
                         "seed is the base seed)")
    if args.out is None:
        raise ValueError("--seeds needs --out (the campaign folder)")
    if resume_campaign and args.overwrite:
        opt = "--continue" if args.continue_ else "--resume"
        raise ValueError(f"{opt} keeps the finished runs in --out: without --overwrite")
    seeds = parse_seeds(args.seeds)
    run_all = train_sweep if cfg.sweep else train_seeds
    try:
        with make_executor(use_ray, address=args.address, num_cpus=args.num_cpus) as ex:
            out = run_all(cfg, seeds, args.out, overwrite=args.overwrite, executor=ex,
                          resume=resume_campaign)
    except KeyboardInterrupt:
        if not (Path(args.out) / "config.yaml").is_file():
            raise
        print(f"dss14 train: campaign interrupted; the finished runs in {args.out} are kept, "
              f"the others train anew; continue with: {campaign_resume_command(args)}",
              file=sys.stderr)
        return 130
    if cfg.sweep:
        n = len(cfg.points())
        print(f"{counted(n, 'point')} x {counted(len(seeds), 'seed')}: per point a campaign folder "
              f"(summary.json, learning curves), sweep.json and sweep.md written to {out}")
    else:
        print((Path(out) / "summary.md").read_text())
        print(f"{counted(len(seeds), 'run')}, summary.json, summary.md (above) and learning curves "
              f"written to {out}")
    return 0


def _policy_option(path: str | None) -> str | None:
    """``--ppo-model`` as a policy path: a training campaign folder stands for its best seed's
    ``eval/best`` (said on stderr).
    """
    if path is None:
        return None
    from dss14_env.agents.campaign import best_seed_policy, is_campaign_folder

    if not is_campaign_folder(path):
        return path
    best, note = best_seed_policy(path)
    print(f"dss14: {note}", file=sys.stderr)
    return str(best)


def _bench(args: argparse.Namespace) -> int:
    import shlex

    from dss14_env.bench.bench import bench, build_plan, prepare_out
    from dss14_env.bench.plan import parse_episodes

    args.ppo_model = _policy_option(args.ppo_model)
    cmd = "dss14 " + shlex.join(args.argv)
    seeds = parse_episodes(args.episodes) if args.episodes is not None else args.seeds
    plan = build_plan(controllers=args.controllers, scenarios=args.scenarios, seeds=seeds,
                      wind_speeds=args.wind_speeds, steps=args.steps, quick=args.quick,
                      ppo_model=args.ppo_model, randomize=args.randomize, out=args.out,
                      figures=not args.no_figures, sweep=not args.no_sweep,
                      sweep_seeds=args.sweep_seeds, sequential_episodes=args.sequential_episodes,
                      threads=args.threads, overwrite=args.overwrite, command=cmd,
                      variants=args.variants)
    prepare_out(plan)  # before any work: a bad --out is a one-line error
    for note in plan.notes:
        print(f"dss14 bench: warning: {note}", file=sys.stderr)
    print(plan.describe(), flush=True)
    res = bench(plan, progress=not args.no_progress)
    print("The dish's true pointing error in the holds:")
    print(res["headline"])
    print(f"results.json, results.md and {len(res['figures'])} figures written to {plan.out} "
          f"in {res['wall_time_s']:.1f} s")
    return 0


def _campaign(args: argparse.Namespace) -> int:
    import shlex

    from dss14_env.bench import campaign as C
    from dss14_env.bench.campaign_report import parse_requirements
    from dss14_env.core.parallel import check_ray_options, make_executor, probe_address, require_ray

    args.ppo_model = _policy_option(args.ppo_model)
    speeds = C.parse_wind_speeds(args.wind_speeds, C.CampaignOptionError, hint="")
    given = {k: v for k, v in (("controllers", args.controllers), ("plants", args.plants),
                               ("first_plant", args.first_plant), ("steps", args.steps),
                               ("chunk_size", args.chunk_size), ("ppo_model", args.ppo_model),
                               ("wind_speeds_kmh", speeds),
                               ("directions", C.parse_directions(args.directions))) if v is not None}
    spec = C.CampaignSpec(**given, condition_on_pi=not args.unconditioned)
    reqs = parse_requirements(args.requirements)
    C.check_policy(spec)  # before any work: a policy that cannot act on the environment
    use_ray = args.ray or args.address is not None or args.num_cpus is not None
    if use_ray:  # before any work: bad Ray options, or no Ray (then how to install it)
        check_ray_options(args.address, args.num_cpus)
        require_ray()
        probe_address(args.address)

    def executor():
        return make_executor(use_ray, address=args.address, num_cpus=args.num_cpus)

    where = "Ray " + (f"at {args.address}" if args.address else "(local)") if use_ray else "in-process"
    print(f"campaign: {spec.plants} plants x {len(spec.conditions)} wind conditions x "
          f"{len(spec.names)} controllers = {spec.n_episodes} episodes of {spec.steps} steps, "
          f"{counted(len(spec.chunks()), 'chunk')}, {where}", flush=True)
    try:
        res = C.run_campaign(spec, args.out, executor=executor, requirements=reqs, resume=args.resume,
                             overwrite=args.overwrite, figures=not args.no_figures,
                             progress=not args.no_progress, command="dss14 " + shlex.join(args.argv))
    except KeyboardInterrupt:
        if not (Path(args.out) / "campaign.json").is_file():
            raise
        again = [a for a in args.argv if a not in ("--overwrite", "--resume", "--continue")]
        again.append("--resume")
        print(f"dss14 campaign: interrupted; the finished chunks are in {args.out}/chunks; "
              f"continue with: dss14 {shlex.join(again)}", file=sys.stderr)
        return 130
    print(res["table"])
    print(f"results.json, results.md and {len(res['figures'])} figures written to {res['out']} "
          f"({counted(len(res['computed']), 'chunk')} computed, "
          f"{len(res['resumed'])} read back) in "
          f"{res['results']['campaign']['wall_time_s']['total']:.1f} s")
    return 0


def _add_campaign_parser(sub: Any) -> None:
    p = sub.add_parser("campaign", help="robustness campaign: controllers over plants drawn from "
                       "the report's parameter ranges, in chunks, in-process or on Ray",
                       description="N plants drawn from the report's hydraulic parameter ranges "
                       "(stable part) x wind speeds x directions x controllers, hold episodes in "
                       "chunks; writes results.json, results.md and a CDF figure per wind speed; "
                       "--resume continues an interrupted campaign (docs/scale.md).")
    p.add_argument("--plants", type=int, default=None, metavar="N", help="number of plants (default 200)")
    p.add_argument("--first-plant", type=int, default=None, metavar="K",
                   help="index of the first plant (default 0): plants K .. K+N-1")
    p.add_argument("--controllers", nargs="+", metavar="NAME", default=None,
                   help=catalog.choices_help(catalog.controller_names(),
                                             catalog.controller_names("campaign")))
    p.add_argument("--ppo-model", default=None, metavar="PATH",
                   help=f"a trained policy instead of the {catalog.POLICY_OPTION_ROW} row's "
                   "shipped one, scored under its own name (its folder's)")
    p.add_argument("--unconditioned", action="store_true",
                   help="draw the plants without conditioning on the report's PI being stable (only "
                   "the drive must be): results.md gives each controller's unstable share")
    p.add_argument("--wind-speeds", nargs="+", metavar="KMH", default=None,
                   help="mean wind speeds, km/h (default 50)")
    p.add_argument("--directions", nargs="+", metavar="DIR", default=None,
                   help="front, side or degrees from the boresight (default: front side)")
    p.add_argument("--steps", type=int, default=None,
                   help="episode length, control periods of the environment's dt (default 1500: 30 s "
                   "at 0.02 s; 5-s warm-up)")
    p.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help="plants per chunk, the unit of work and of resuming (default 5)")
    p.add_argument("--requirements", nargs="+", metavar="NAME=MDEG", default=None,
                   help="pointing requirements on the 3-sigma pointing error (default: Ka=2 X=8)")
    p.add_argument("--ray", action="store_true", help="run the chunks as Ray tasks (a local Ray by default)")
    p.add_argument("--address", default=None,
                   help="join a running Ray cluster: 'auto' or its address (implies --ray)")
    p.add_argument("--num-cpus", type=int, default=None, metavar="N",
                   help="CPUs of the local Ray (implies --ray; default: all of the machine's)")
    p.add_argument("--out", default="campaign_out", help="output folder (default: campaign_out)")
    p.add_argument("--resume", "--continue", dest="resume", action="store_true",
                   help="continue the campaign in --out: finished chunks are read back "
                   "(--continue: the same)")
    p.add_argument("--overwrite", action="store_true", help="replace a campaign in --out")
    p.add_argument("--no-figures", action="store_true", help="results.json and results.md only")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_campaign)


def _import_plugins(argv: list[str] | None) -> None:
    """Import the modules of ``--plugin`` (before the options are built, so that the rows they
    register are in the choices and the help).

    :raises SystemExit: a module that cannot be imported (status 2, one line)
    """
    import importlib

    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--plugin", action="append", default=[])
    known, _ = pre.parse_known_args(argv)
    for module in known.plugin:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            print(f"dss14: error: --plugin {module}: {_one_line(exc)}", file=sys.stderr)
            raise SystemExit(2) from None


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``dss14`` console script."""
    _import_plugins(argv)
    parser = argparse.ArgumentParser(prog="dss14", description="DSS-14 antenna servo model and tools")
    parser.add_argument("--plugin", action="append", default=[], metavar="MODULE",
                        help="import MODULE first: its controllers and scenarios, registered with "
                        "dss14_env.bench.catalog.register_controller / register_scenario, join "
                        "the bench and the campaign (repeatable)")
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
                   help="training YAML, or a shipped training config's name ("
                   + "; ".join(f"{algo}: {', '.join(names)}"
                               for algo, names in shipped_training_configs_by_algo().items())
                   + "); default: configs/<algo>.yaml, on --resume the run's")
    p.add_argument("--env", default=None, metavar="ID",
                   help="take the shipped hyperparameters of this environment id "
                   "(configs/hyperparams/<algo>.yml) instead of --config")
    p.add_argument("--out", default=None,
                   help="run folder (default: runs/<algo>-<timestamp>/); with --seeds the "
                   "campaign folder")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run files already in --out (a finished or interrupted run)")
    p.add_argument("--resume", nargs="?", const=LATEST, default=None, metavar="CHECKPOINT",
                   help="continue: a run from a checkpoint folder (<run>/checkpoints/<N>_steps), "
                   "or without one from the last checkpoint of the run in --out; with --seeds the "
                   "interrupted campaign in --out (finished runs are scored, not retrained)")
    p.add_argument("--trust-pickle", action="store_true",
                   help="allow --resume from a stable-baselines3 .zip (unpickled: it can run "
                   "code; only for files you trust)")
    p.add_argument("--env-module", default=None, metavar="MODULE",
                   help="import this module of yours first, to register the env_id it trains on "
                   "(importing runs its code: a configuration file can never ask for it)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar of a single run (default: on when stderr is a terminal, "
                   "else the config's progress_bar)")
    p.add_argument("--timesteps", type=int, default=None, help="override total_timesteps")
    p.add_argument("--seed", type=int, default=None, help="override seed")
    p.add_argument("--seeds", nargs="+", default=None, metavar="K",
                   help="one run per seed index into --out/seed_<k>/ (0-4, or 0 3 7), then "
                   "summary.json and learning curves; with a sweep in the config, one such "
                   "campaign per point into --out/<point>/, then sweep.json and sweep.md")
    p.add_argument("--continue", dest="continue_", action="store_true",
                   help="with --seeds: the same as --resume (the name of earlier versions)")
    p.add_argument("--ray", action="store_true",
                   help="with --seeds: the runs as Ray tasks, on a local Ray by default (docs/scale.md)")
    p.add_argument("--address", default=None,
                   help="with --seeds: join a running Ray cluster, 'auto' or its address (implies "
                   "--ray; --out on a folder every node can write)")
    p.add_argument("--num-cpus", type=int, default=None, metavar="N",
                   help="with --seeds: CPUs of the local Ray (implies --ray; default all)")
    p.set_defaults(func=_train)
    p = sub.add_parser("bench", help="score PI, LQG, MPC and PPO on the same scenarios and seeds",
                       description="Run every controller through the runner on the same "
                       "scenarios and seeds; write results.json, results.md and PNG figures, every "
                       "figure with its 95 % confidence interval (docs/bench.md).")
    p.add_argument("--quick", action="store_true",
                   help="short version for CI: few, short episodes, wind speeds "
                   f"{' '.join(f'{v:g}' for v in QUICK_WIND_SPEEDS_KMH)} (under 30 s)")
    seeds = p.add_mutually_exclusive_group()
    seeds.add_argument("--episodes", default=None, metavar="N",
                       help="episodes of the batched controllers in every scenario: seeds 0..N-1 "
                       "(default: each scenario's count, e.g. 128 for hold)")
    seeds.add_argument("--seeds", nargs="+", metavar="SEED", default=None,
                       help="the seeds of the batched controllers' episodes in every scenario, as in "
                       "every command: seeds and ranges, e.g. 0 3 7 or 0-4 (one value: that seed)")
    p.add_argument("--sequential-episodes", type=int, default=None, metavar="M",
                   help="episodes of the controllers that run one at a time (MPC): the first M seeds "
                   "of every scenario and sweep point (default: each scenario's, e.g. 16 for hold)")
    p.add_argument("--controllers", nargs="+", metavar="NAME", default=None,
                   help=catalog.choices_help(catalog.controller_names(),
                                             catalog.controller_names("bench")))
    p.add_argument("--scenarios", nargs="+", metavar="NAME", default=None,
                   help=catalog.choices_help(catalog.scenario_names(), catalog.scenario_names("bench")))
    p.add_argument("--wind-speeds", nargs="+", metavar="KMH", default=None,
                   help="speeds of the error-vs-wind sweep, km/h (default: the environment's "
                   "wind_speed_grid_kmh, configs/env.yaml)")
    p.add_argument("--no-sweep", action="store_true", help="skip the error-vs-wind sweep")
    p.add_argument("--variants", nargs="*", metavar="NAME", default=None,
                   help="drive variants whose hold scenarios also run "
                   f"({', '.join(f'{v.name}: {v.description}' for v in DRIVE_VARIANTS.values())}; "
                   "default: all, none with --quick; --variants alone: none)")
    p.add_argument("--sweep-seeds", type=int, default=None, metavar="N",
                   help="episodes per sweep point of the batched controllers: the first N of "
                   "--seeds, or seeds 0..N-1 (default 32, or every seed of --seeds)")
    p.add_argument("--steps", type=int, default=None,
                   help="episode length of every scenario and sweep point, control periods "
                   "(default: the scenario's; one period is the environment's dt)")
    p.add_argument("--ppo-model", default=None, metavar="PATH",
                   help=f"a trained policy (run folder, eval/best or a checkpoint folder) instead of "
                   f"the {catalog.POLICY_OPTION_ROW} row's shipped one, scored under its own name "
                   "(its folder's)")
    p.add_argument("--randomize", action="store_true",
                   help="randomised plant parameters every episode (randomize_params=True)")
    p.add_argument("--threads", type=int, default=1, metavar="N",
                   help="BLAS threads of numpy and scipy while running (default 1)")
    p.add_argument("--out", default="bench_out", help="output folder (default: bench_out)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of an earlier bench in --out (results.json, results.md, "
                   "its figures; nothing else)")
    p.add_argument("--no-figures", action="store_true", help="results.json and results.md only")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_bench)
    _add_campaign_parser(sub)
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
        print(f"dss14 {args.command}: interrupted{_again(args)}", file=sys.stderr)
        return 130


def _again(args: argparse.Namespace) -> str:
    """``; start again with: <command>`` for an interrupted command that keeps nothing to
    continue from (its files so far are in its manifest, so ``--overwrite`` replaces them).
    """
    import shlex

    argv = getattr(args, "argv", None)
    if argv is None or args.command not in ("bench", "reproduce"):
        return ""
    again = [a for a in argv if a != "--overwrite"] + ["--overwrite"]
    return f"; start again with: dss14 {shlex.join(again)}"


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
