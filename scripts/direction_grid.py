"""Run the wind direction and speed grid (:mod:`dss14_env.bench.grid`) and write its results.

The hold scenario at wind directions 0-180 degrees in 45-degree steps at 50 km/h and at 10 and
70 km/h from the front and the side, for the report's PI, the pointing LQG, the pointing LQG
scheduled on the measured wind speed and the monopulse LQG (and a trained policy with
``--ppo-model PATH``), scored on the dish's pointing error (el
and xel) with 95 % intervals and paired ratios to the PI::

    python scripts/direction_grid.py                        # docs/results/direction_grid.{json,md}
    python scripts/direction_grid.py --ppo-model runs/x/eval/best --out-json grid.json --out-md grid.md
    python scripts/direction_grid.py --render               # the table again from the JSON

About a minute of CPU (one core; BLAS on one thread), the wall time printed at the end.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

from dss14_env.bench.grid import EPISODES, SECONDS, grid_controllers, grid_table, run_grid
from dss14_env.bench.report import results_json
from dss14_env.bench.threads import blas_threads
from dss14_env.core.outdir import atomic_write_text

ROOT = Path(__file__).resolve().parents[1]
OUT_JSON = ROOT / "docs" / "results" / "direction_grid.json"
OUT_MD = ROOT / "docs" / "results" / "direction_grid.md"
TITLE = "# Pointing error over wind directions and speeds (hold scenario)\n\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ppo-model", default=None, help="a trained policy (run folder, eval/best folder or "
                    "zip): its column is added under its own name")
    ap.add_argument("--controllers", nargs="+", default=None, help="catalog controllers (default: pi_kp1 "
                    "lqg_pointing lqg_pointing_sched lqg_monopulse)")
    ap.add_argument("--episodes", type=int, default=EPISODES,
                    help=f"episodes per grid point (default {EPISODES})")
    ap.add_argument("--seconds", type=float, default=SECONDS, help=f"episode length, s (default {SECONDS:g})")
    ap.add_argument("--out-json", default=str(OUT_JSON))
    ap.add_argument("--out-md", default=str(OUT_MD))
    ap.add_argument("--render", action="store_true", help="only write the table from --out-json")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        if args.render:
            results = json.loads(Path(args.out_json).read_text())
        else:
            ctrls = grid_controllers(args.controllers, args.ppo_model)
            for p in (args.out_json, args.out_md):
                if not Path(p).parent.is_dir():
                    raise ValueError(f"{p}: its folder does not exist")

            def tick(line: str, n: int) -> None:
                print(line, file=sys.stderr, flush=True)

            given = argv if argv is not None else sys.argv[1:]
            command = "python scripts/direction_grid.py " + shlex.join(given)
            with blas_threads(1):
                results = run_grid(ctrls, args.episodes, args.seconds, tick, command.strip())
            atomic_write_text(Path(args.out_json), results_json(results))
        atomic_write_text(Path(args.out_md), TITLE + grid_table(results))
    except (OSError, ValueError) as exc:
        print(f"direction_grid: {exc}", file=sys.stderr)
        return 2
    print(grid_table(results))
    print(f"{args.out_json} and {args.out_md} written; wall time {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
