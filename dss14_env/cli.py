"""Command-line interface: ``dss14 <subcommand>``."""

from __future__ import annotations

import argparse
import sys
import time


def _reproduce(args: argparse.Namespace) -> int:
    from .config import load_model_config
    from .model import build_model, default_model
    from .reproduce import reproduce

    t0 = time.perf_counter()
    model = build_model(load_model_config(args.config)) if args.config else default_model()
    res = reproduce(args.out, model, figures=not args.no_figures)
    print(res["markdown"])
    bad = [k for k, v in res["metrics"].items() if v["ok"] is False]
    print(f"{len(res['figures'])} figures, metrics.json and metrics.md written to {args.out} "
          f"in {time.perf_counter() - t0:.1f} s")
    if bad:
        print(f"outside the accepted range: {', '.join(bad)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``dss14`` console script."""
    parser = argparse.ArgumentParser(prog="dss14", description="DSS-14 antenna servo model and tools")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("reproduce", help="redraw the report's figures and check its numbers")
    p.add_argument("--out", default="reproduce_out", help="output folder (default: reproduce_out)")
    p.add_argument("--config", default=None, help="model YAML (default: the shipped configs/model.yaml)")
    p.add_argument("--no-figures", action="store_true", help="metrics only")
    p.set_defaults(func=_reproduce)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, KeyError, RuntimeError) as exc:  # config errors etc.: one clear line
        print(f"dss14 {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
