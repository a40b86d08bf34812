"""Command-line interface: ``dss14 <subcommand>``."""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from dss14_env.agents.config_files import shipped_training_configs_by_algo
from dss14_env.bench import catalog
from dss14_env.bench.plan import QUICK_WIND_SPEEDS_KMH
from dss14_env.core.progress import LINE_EVERY_S
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
    prepare_output_dir(args.out, OWNED_FILES, overwrite=args.overwrite, command="reproduce")
    with manifest_kept(args.out):
        model = build_model(cfg) if cfg is not None else default_model()
        res = reproduce(args.out, model, figures=not args.no_figures, progress=args.progress)
    print(res["table"])
    print(f"{counted(len(res['figures']), 'figure')}, metrics.json and metrics.md (every row by its "
          f"key) written to {args.out} in {time.perf_counter() - t0:.1f} s")
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
#: options of earlier versions, refused with the name that replaced them
RENAMED = {"train": {"seeds": ("--seeds", "--train-seeds (training-seed indices; --seeds names "
                                          "episode seeds in bench)"),
                     "continue_": ("--continue", "--resume")},
           "campaign": {"continue_": ("--continue", "--resume")}}


def refuse_renamed(args: argparse.Namespace) -> None:
    """One line for an option of an earlier version, naming the one that replaced it."""
    for dest, (old, new) in RENAMED.get(args.command, {}).items():
        if getattr(args, dest, None) not in (None, False):
            raise ValueError(f"{old}: is now {new}")


def _train_resume(args: argparse.Namespace) -> tuple[str | None, bool]:
    """``(checkpoint to resume a single run from, or None; whether a --train-seeds campaign is
    continued)`` from ``--resume [CHECKPOINT]``.
    """
    from dss14_env.agents.train import last_checkpoint

    resume = args.resume
    if args.train_seeds is not None:
        if resume not in (None, LATEST):
            raise ValueError("--resume: with --train-seeds it continues the campaign in --out and "
                             "takes no checkpoint (--train-seeds ... --out DIR --resume)")
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
    """The one command that continues an interrupted ``dss14 train --train-seeds`` campaign."""
    import shlex

    cmd = ["dss14", "train", args.algo, "--config", str(Path(args.out) / "config.yaml"),
           "--train-seeds", *args.train_seeds, "--out", str(args.out), "--resume"]
    if args.env_module:
        cmd += ["--env-module", args.env_module]
    if args.address is not None:
        cmd += ["--address", args.address]
    elif args.num_cpus is not None:
        cmd += ["--num-cpus", str(args.num_cpus)]
    elif args.ray:
        cmd += ["--ray"]
    return shlex.join(cmd)


def say_run(cfg: Any, out: str | None, resume: str | None) -> None:
    """A single run's first line on stderr, before its environment is checked and its model is
    built (seconds): what it trains, how long, where (a campaign says its own,
    :func:`dss14_env.agents.campaign.say_plan`).
    """
    where = (out if out is not None else "the checkpoint's run folder" if resume is not None
             else f"a new folder runs/{cfg.algo}-<date>-<time>")
    what = f"continuing {resume} to" if resume is not None else "one run of"
    print(f"{cfg.algo} on {cfg.env_id}: {what} {cfg.total_timesteps} steps into {where}",
          file=sys.stderr, flush=True)


def _train(args: argparse.Namespace) -> int:
    from dss14_env.agents.campaign import COMMAND, kept_work, owned_files, parse_seeds, train_seeds
    from dss14_env.agents.sweep import train_sweep
    from dss14_env.agents.train import TrainingInterrupted, check_run_first, config_for_command, train
    from dss14_env.core.outdir import prepare_output_dir
    from dss14_env.core.parallel import make_executor, ray_preflight
    from dss14_env.core.stop import exit_status, signal_name, signal_of

    refuse_renamed(args)
    use_ray = args.ray or args.address is not None or args.num_cpus is not None
    resume, resume_campaign = _train_resume(args)
    cfg = config_for_command(args.algo, args.config, args.env, resume, args.timesteps,
                             args.seed, args.env_module)
    if cfg.sweep and (args.train_seeds is None or args.out is None):
        raise ValueError(f"{cfg.source}: field 'sweep': a sweep trains one campaign per point: "
                         f"give --train-seeds (e.g. 0-4) and --out")
    if use_ray:  # before Ray starts: bad options, an unusable --out, or no Ray (how to install it)
        if args.train_seeds is None or args.out is None:
            raise ValueError("--ray runs the runs of --train-seeds as Ray tasks: give --train-seeds "
                             "and --out")
        parse_seeds(args.train_seeds)
        ray_preflight(args.address, args.num_cpus)
        if not resume_campaign:  # checked only: nothing removed before the runs are checked
            prepare_output_dir(args.out, owned_files(args.out), args.overwrite, dry_run=True,
                               command=COMMAND)
    if args.train_seeds is None:
        if args.progress:
            check_run_first(args.out, resume, args.overwrite, args.trust_pickle)
            say_run(cfg, args.out, resume)
        try:
            run = train(cfg, run_dir=args.out, resume=resume, overwrite=args.overwrite,
                        trust_pickle=args.trust_pickle, progress=args.progress)
        except TrainingInterrupted as exc:
            print(f"dss14 train: {exc.message}", file=sys.stderr)
            return exc.exit_status
        print(f"{cfg.algo} run written to {run} (policy folder: policy.pt, normalization.npz, "
              f"config.yaml)")
        return 0
    if args.seed is not None:
        raise ValueError("--train-seeds trains one run per seed index: without --seed (the "
                         "config's seed is the base seed)")
    if args.out is None:
        raise ValueError("--train-seeds needs --out (the campaign folder)")
    if resume_campaign and args.overwrite:
        raise ValueError("--resume keeps the finished runs in --out: without --overwrite")
    seeds = parse_seeds(args.train_seeds)
    run_all = train_sweep if cfg.sweep else train_seeds
    try:
        with make_executor(use_ray, address=args.address, num_cpus=args.num_cpus) as ex:
            out = run_all(cfg, seeds, args.out, overwrite=args.overwrite, executor=ex,
                          resume=resume_campaign, progress=args.progress)
    except KeyboardInterrupt as exc:
        if not (Path(args.out) / "config.yaml").is_file():
            raise
        kept = ("every point's finished runs and each other run's last checkpoint" if cfg.sweep
                else kept_work(cfg, args.out, seeds))
        print(f"dss14 train: campaign stopped ({signal_name(signal_of(exc))}); kept in "
              f"{args.out}: {kept}; continue with: {campaign_resume_command(args)}", file=sys.stderr)
        return exit_status(exc)
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

    from dss14_env.bench.bench import COMMAND, OWNED_FILES, bench, build_plan, prepare_out
    from dss14_env.bench.plan import parse_episodes
    from dss14_env.core.outdir import prepare_output_dir

    # the folder first: checked before any policy is loaded (seconds), nothing made or removed
    prepare_output_dir(args.out, OWNED_FILES, args.overwrite, dry_run=True, command=COMMAND)
    args.ppo_model = _policy_option(args.ppo_model)
    cmd = "dss14 " + shlex.join(args.argv)
    seeds = parse_episodes(args.episodes) if args.episodes is not None else args.seeds
    plan = build_plan(controllers=args.controllers, scenarios=args.scenarios, seeds=seeds,
                      wind_speeds=args.wind_speeds, steps=args.steps, quick=args.quick,
                      ppo_model=args.ppo_model, randomize=args.randomize, out=args.out,
                      figures=not args.no_figures, sweep=not args.no_sweep,
                      sweep_seeds=args.sweep_seeds, sequential_episodes=args.sequential_episodes,
                      threads=args.threads, overwrite=args.overwrite, command=cmd,
                      variants=args.variants, jobs=args.jobs)
    prepare_out(plan)  # before any work: a bad --out is a one-line error
    for note in plan.notes:
        print(f"dss14 bench: warning: {note}", file=sys.stderr)
    print(plan.describe(), flush=True)
    res = bench(plan, progress=args.progress)
    print("The dish's true pointing error in the holds:")
    print(res["headline"])
    print(f"results.json, results.md and {counted(len(res['figures']), 'figure')} written to "
          f"{plan.out} in {res['wall_time_s']:.1f} s")
    return 0


def _campaign(args: argparse.Namespace) -> int:
    import shlex

    from dss14_env.bench import campaign as C
    from dss14_env.bench.campaign_report import parse_requirements
    from dss14_env.core.outdir import prepare_output_dir
    from dss14_env.core.parallel import make_executor, ray_preflight

    refuse_renamed(args)
    args.ppo_model = _policy_option(args.ppo_model)
    speeds = C.parse_wind_speeds(args.wind_speeds, C.CampaignOptionError, hint="")
    given = {k: v for k, v in (("controllers", args.controllers), ("plants", args.plants),
                               ("first_plant", args.first_plant), ("steps", args.steps),
                               ("chunk_size", args.chunk_size), ("ppo_model", args.ppo_model),
                               ("wind_speeds_kmh", speeds),
                               ("directions", C.parse_directions(args.directions))) if v is not None}
    spec = C.CampaignSpec(**given, condition_on_pi=not args.unconditioned)
    reqs = parse_requirements(args.requirements)
    if not (Path(args.out) / "campaign.json").is_file():  # a new campaign's folder: before any policy loads
        prepare_output_dir(args.out, C.OWNED, args.overwrite, dry_run=True, command=C.COMMAND)
    C.check_policy(spec)  # before any work: a policy that cannot act on the environment
    use_ray = args.ray or args.address is not None or args.num_cpus is not None
    # before any work: bad Ray options, no Ray (then how to install it), no cluster answering
    target = ray_preflight(args.address, args.num_cpus) if use_ray else None

    def executor():
        return make_executor(use_ray, address=args.address, num_cpus=args.num_cpus)

    where = target.describe() if target is not None else "in-process"
    print(f"campaign: {counted(spec.plants, 'plant')} x {counted(len(spec.conditions), 'wind condition')} "
          f"x {counted(len(spec.names), 'controller')} = {counted(spec.n_episodes, 'episode')} of "
          f"{spec.steps} steps, "
          f"{counted(len(spec.chunks()), 'chunk')}, {where}", flush=True)
    try:
        res = C.run_campaign(spec, args.out, executor=executor, requirements=reqs, resume=args.resume,
                             overwrite=args.overwrite, figures=not args.no_figures,
                             progress=args.progress, command="dss14 " + shlex.join(args.argv))
    except KeyboardInterrupt as exc:
        if not (Path(args.out) / "campaign.json").is_file():
            raise
        from dss14_env.core.stop import exit_status, signal_name, signal_of

        again = [a for a in args.argv if a not in ("--overwrite", "--resume")]
        again.append("--resume")
        print(f"dss14 campaign: stopped ({signal_name(signal_of(exc))}); the finished chunks are "
              f"kept in {args.out}/chunks; continue with: dss14 {shlex.join(again)}", file=sys.stderr)
        return exit_status(exc)
    print(res["table"])
    print(f"results.json, results.md and {counted(len(res['figures']), 'figure')} written to {res['out']} "
          f"({counted(len(res['computed']), 'chunk')} computed, "
          f"{len(res['resumed'])} read back) in "
          f"{res['results']['campaign']['wall_time_s']['total']:.1f} s")
    return 0


def _budgets_help(field: str | None = None, quick: bool = False) -> str:
    """The default bench scenarios' budgets from the catalog: one field (``episodes``,
    ``sequential``), or episodes x seconds (one at a time) of each.
    """
    from dss14_env.bench.plan import DEFAULT_BUDGETS, DEFAULT_SCENARIOS, QUICK_BUDGETS

    budgets = QUICK_BUDGETS if quick else DEFAULT_BUDGETS
    if field is not None:
        return ", ".join(f"{s} {getattr(budgets[s], field)}" for s in DEFAULT_SCENARIOS)
    return ", ".join(f"{s} {b.episodes} x {b.seconds:g} s ({b.sequential})"
                     for s, b in ((s, budgets[s]) for s in DEFAULT_SCENARIOS))


def _add_progress(p: argparse.ArgumentParser, what: str) -> None:
    """The one progress option of every long command."""
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True,
                   help=f"{what} on stderr as they are done: a bar with its ETA on a terminal, "
                   f"else a line every tenth or {LINE_EVERY_S:g} s (default: on)")


def _add_campaign_parser(sub: Any) -> None:
    from dss14_env.bench import campaign_spec as S
    from dss14_env.bench.campaign_report import DEFAULT_REQUIREMENTS

    p = sub.add_parser("campaign", help="robustness campaign: controllers over plants drawn from "
                       "the report's parameter ranges, in chunks, in-process or on Ray",
                       description="N plants drawn from the report's hydraulic parameter ranges "
                       "(stable part) x wind speeds x directions x controllers, hold episodes in "
                       "chunks; writes results.json, results.md and a CDF figure per wind speed; "
                       "--resume continues an interrupted campaign (docs/scale.md).")
    p.add_argument("--plants", type=int, default=None, metavar="N",
                   help=f"number of plants (default {S.DEFAULT_PLANTS})")
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
                   help="mean wind speeds, km/h (default "
                   + " ".join(f"{v:g}" for v in S.DEFAULT_WIND_SPEEDS_KMH) + ")")
    p.add_argument("--directions", nargs="+", metavar="DIR", default=None,
                   help="front, side or degrees from the boresight (default: "
                   f"{' '.join(map(str, S.DEFAULT_DIRECTIONS))})")
    p.add_argument("--steps", type=int, default=None,
                   help=f"episode length, control periods of the environment's dt (default "
                   f"{S.DEFAULT_STEPS}; the first {S.WARMUP_S:g} s are a warm-up)")
    p.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help=f"plants per chunk, the unit of work and of resuming (default "
                   f"{S.DEFAULT_CHUNK_SIZE})")
    p.add_argument("--requirements", nargs="+", metavar="NAME=MDEG", default=None,
                   help="pointing requirements on the 3-sigma pointing error (default: "
                   + " ".join(f"{k}={v:g}" for k, v in DEFAULT_REQUIREMENTS.items()) + ")")
    p.add_argument("--ray", action="store_true", help="run the chunks as Ray tasks (a local Ray by default)")
    p.add_argument("--address", default=None,
                   help="join a running Ray cluster: 'auto' or its address (implies --ray)")
    p.add_argument("--num-cpus", type=int, default=None, metavar="N",
                   help="CPUs of the local Ray (implies --ray; default: all of the machine's)")
    p.add_argument("--out", default="campaign_out", help="output folder (default: campaign_out)")
    p.add_argument("--resume", action="store_true",
                   help="continue the campaign in --out: finished chunks are read back")
    p.add_argument("--continue", dest="continue_", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--overwrite", action="store_true", help="replace a campaign in --out")
    p.add_argument("--no-figures", action="store_true", help="results.json and results.md only")
    _add_progress(p, "the chunks")
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
    with report_stream():  # every line it writes, its errors included
        _import_plugins(argv)
        args = build_parser().parse_args(argv)
        args.argv = list(argv) if argv is not None else sys.argv[1:]
        return run_command(args)


def build_parser() -> argparse.ArgumentParser:
    """The parser of every subcommand (``dss14 --help``)."""
    from dss14_env import __version__
    from dss14_env.bench.plan import DEFAULT_SWEEP, default_wind_speeds

    parser = argparse.ArgumentParser(prog="dss14", description="DSS-14 antenna servo model and tools")
    parser.add_argument("--version", action="version", version=f"dss14 {__version__}")
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
    _add_progress(p, "the stages")
    p.set_defaults(func=_reproduce)
    p = sub.add_parser("train", help="train a learned controller (PPO, RecurrentPPO, SAC)",
                       description="Train one run (or one per seed with --train-seeds) into a run "
                       "folder (docs/rl.md). Ctrl-C or SIGTERM stops every run at its next step "
                       "with a checkpoint there and prints the command that continues (--resume).")
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
                   help="run folder (default: runs/<algo>-<timestamp>/); with --train-seeds the "
                   "campaign folder")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run files already in --out (a finished or interrupted run)")
    p.add_argument("--resume", nargs="?", const=LATEST, default=None, metavar="CHECKPOINT",
                   help="continue: a run from a checkpoint folder (<run>/checkpoints/<N>_steps), "
                   "or without one from the last checkpoint of the run in --out; with "
                   "--train-seeds the interrupted campaign in --out (finished runs are scored, "
                   "not retrained; the others continue from their last checkpoint)")
    p.add_argument("--trust-pickle", action="store_true",
                   help="allow --resume from a stable-baselines3 .zip (unpickled: it can run "
                   "code; only for files you trust)")
    p.add_argument("--env-module", default=None, metavar="MODULE",
                   help="import this module of yours first, to register the env_id it trains on "
                   "(importing runs its code: a configuration file can never ask for it)")
    _add_progress(p, "each run's environment steps")
    p.add_argument("--timesteps", type=int, default=None, help="override total_timesteps")
    p.add_argument("--seed", type=int, default=None, help="override seed")
    p.add_argument("--train-seeds", nargs="+", default=None, metavar="K",
                   help="one run per training-seed index into --out/seed_<k>/ (0-4, or 0 3 7), then "
                   "summary.json and learning curves; with a sweep in the config, one such "
                   "campaign per point into --out/<point>/, then sweep.json and sweep.md")
    p.add_argument("--seeds", nargs="+", default=None, help=argparse.SUPPRESS)
    p.add_argument("--continue", dest="continue_", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--ray", action="store_true",
                   help="with --train-seeds: the runs as Ray tasks, on a local Ray by default "
                   "(docs/scale.md)")
    p.add_argument("--address", default=None,
                   help="with --train-seeds: join a running Ray cluster, 'auto' or its address "
                   "(implies --ray; --out on a folder every node can write)")
    p.add_argument("--num-cpus", type=int, default=None, metavar="N",
                   help="with --train-seeds: CPUs of the local Ray (implies --ray; default all)")
    p.set_defaults(func=_train)
    p = sub.add_parser("bench", help="score PI, LQG, MPC and PPO on the same scenarios and seeds",
                       description="Run every controller through the runner on the same "
                       "scenarios and seeds; write results.json, results.md and PNG figures, every "
                       "figure with its 95 % confidence interval (docs/bench.md).")
    p.add_argument("--quick", action="store_true",
                   help="short version for CI: per scenario episodes x length (episodes one at a "
                   "time): " + _budgets_help(quick=True) + "; wind speeds "
                   + " ".join(f"{v:g}" for v in QUICK_WIND_SPEEDS_KMH))
    seeds = p.add_mutually_exclusive_group()
    seeds.add_argument("--episodes", default=None, metavar="N",
                       help="episodes of the batched controllers in every scenario: seeds 0..N-1 "
                       "(default: per scenario " + _budgets_help("episodes") + ")")
    seeds.add_argument("--seeds", nargs="+", metavar="SEED", default=None,
                       help="the seeds of the batched controllers' episodes in every scenario, as in "
                       "every command: seeds and ranges, e.g. 0 3 7 or 0-4 (one value: that seed)")
    p.add_argument("--sequential-episodes", type=int, default=None, metavar="M",
                   help="episodes of the controllers that run one at a time (MPC): the first M seeds "
                   "of every scenario and sweep point (default: per scenario "
                   + _budgets_help("sequential") + ")")
    p.add_argument("--controllers", nargs="+", metavar="NAME", default=None,
                   help=catalog.choices_help(catalog.controller_names(),
                                             catalog.controller_names("bench")))
    p.add_argument("--scenarios", nargs="+", metavar="NAME", default=None,
                   help=catalog.choices_help(catalog.scenario_names(), catalog.scenario_names("bench")))
    p.add_argument("--wind-speeds", nargs="+", metavar="KMH", default=None,
                   help="speeds of the error-vs-wind sweep, km/h (default: "
                   + " ".join(f"{v:g}" for v in default_wind_speeds()) + ")")
    p.add_argument("--no-sweep", action="store_true", help="skip the error-vs-wind sweep")
    p.add_argument("--variants", nargs="*", metavar="NAME", default=None,
                   help="drive variants whose hold scenarios also run "
                   f"({', '.join(f'{v.name}: {v.description}' for v in DRIVE_VARIANTS.values())}; "
                   "default: all, none with --quick; --variants alone: none)")
    p.add_argument("--sweep-seeds", type=int, default=None, metavar="N",
                   help="episodes per sweep point of the batched controllers: the first N of "
                   f"--seeds, or seeds 0..N-1 (default {DEFAULT_SWEEP.episodes}, or every seed of --seeds)")
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
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="worker processes running the scenarios and sweep points side by side, the "
                   "largest first (default: the usable CPUs, at most 8; 1: one process); the "
                   "results are the same for any N")
    p.add_argument("--out", default="bench_out", help="output folder (default: bench_out)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of an earlier bench in --out (results.json, results.md, "
                   "its figures; nothing else)")
    p.add_argument("--no-figures", action="store_true", help="results.json and results.md only")
    _add_progress(p, "the episodes")
    p.set_defaults(func=_bench)
    _add_campaign_parser(sub)
    return parser


def run_command(args: argparse.Namespace) -> int:
    """Run a parsed subcommand; every expected failure becomes one line on stderr.

    Bad input (configuration, options, files) and operating-system errors (a folder that cannot
    be written, a full disk) exit with status 2, an interruption with 130 (Ctrl-C) or 143
    (SIGTERM); a bug still shows its traceback.
    """
    from dss14_env.core.outdir import check_folder_name
    from dss14_env.core.stop import exit_status, signal_name, signal_of, terminate_as_interrupt

    try:
        if getattr(args, "out", None) is not None:
            check_folder_name(args.out)  # before a path of it ('' becomes '.') is made
        with terminate_as_interrupt():
            return args.func(args)
    except (ValueError, KeyError, RuntimeError, OSError) as exc:
        print(f"dss14 {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"dss14 {args.command}: stopped ({signal_name(signal_of(exc))}){_again(args)}",
              file=sys.stderr)
        return exit_status(exc)


class _Report(io.TextIOBase):
    r"""The command's standard output or error: a reader gone away (``| head``) ends the report, not
    the command, and a character the stream's encoding lacks is written as a backslash escape
    (``\u03c3`` for σ under ``PYTHONIOENCODING=ascii``), so that the exit status says how the work
    went, not how its report was read.
    """

    def __init__(self, inner: Any) -> None:
        super().__init__()
        self.inner = inner
        self.gone = False

    @property
    def encoding(self) -> str:  # noqa: D102 - the stream's
        return getattr(self.inner, "encoding", None) or "utf-8"

    def write(self, s: str) -> int:  # noqa: D102 - io.TextIOBase's
        if self.gone:
            return len(s)
        try:
            self.inner.write(s)
        except UnicodeEncodeError:
            self._guarded(lambda: self.inner.write(s.encode(self.encoding, "backslashreplace")
                                                   .decode(self.encoding)))
        except BrokenPipeError:
            self._reader_gone()
        return len(s)

    def flush(self) -> None:  # noqa: D102 - io.TextIOBase's
        if not (self.gone or self.closed):
            self._guarded(self.inner.flush)

    @property
    def closed(self) -> bool:  # noqa: D102 - the stream's
        return bool(getattr(self.inner, "closed", False))

    def isatty(self) -> bool:  # noqa: D102 - the stream's
        return not self.closed and bool(getattr(self.inner, "isatty", lambda: False)())

    def fileno(self) -> int:  # noqa: D102 - the stream's
        return self.inner.fileno()

    def _guarded(self, fn: Any) -> None:
        try:
            fn()
        except BrokenPipeError:
            self._reader_gone()

    def _reader_gone(self) -> None:
        """Nothing more is shown; what the stream still buffers goes nowhere (else Python's
        own flush at exit would fail on the closed pipe).
        """
        self.gone = True
        try:
            fd = self.inner.fileno()
        except (OSError, ValueError, AttributeError):
            return
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)


@contextlib.contextmanager
def report_stream() -> Iterator[None]:
    """Context manager: ``sys.stdout`` and ``sys.stderr`` are each a :class:`_Report` for the block."""
    out, err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _Report(out), _Report(err)
    try:
        yield
    finally:
        for report in (sys.stdout, sys.stderr):
            report.flush()
        sys.stdout, sys.stderr = out, err


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
