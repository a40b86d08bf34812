"""The bench's targets, read from a results.json: time and precision.

* wall time of the whole run against its budget (default run: 300 s, ``--quick``: 30 s, on 2
  cores), with the CPU time of the process and the machine's load average at the start (the
  development machine is shared: the CPU time is what the run costs on a quiet machine);
* the 95 % half-width of the loaded axis' 3σ in the hold scenarios (front wind: el, side
  wind: az) in % of the value, against 5 % for every controller but the MPC (which runs one
  episode at a time and gets what fits the time budget: its wider interval is printed, not
  judged).

::

    dss14 bench --out bench_out && python scripts/bench_targets.py bench_out/results.json

Exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

LOADED = {"hold_front": "el", "hold_side": "az"}
#: controllers whose interval is not judged (one episode at a time by design)
NOT_JUDGED = ("mpc",)
BUDGET_S = {False: 300.0, True: 30.0}
HALF_WIDTH_PCT = 5.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", help="results.json of a bench run")
    args = ap.parse_args(argv)
    try:
        r = json.loads(Path(args.results).read_text())
    except (OSError, ValueError) as exc:
        print(f"bench_targets: cannot read {args.results}: {exc}", file=sys.stderr)
        return 2
    b = r["bench"]
    quick = bool(b["config"]["quick"])
    wall, cpu = b["wall_time_s"]["total"], b.get("cpu_time_s")
    budget = BUDGET_S[quick]
    load = b["machine"].get("load_average_start")
    print(f"{'--quick' if quick else 'default'} run: wall time {wall:.0f} s of {budget:.0f} s "
          f"({wall / budget:.2f}), CPU time {'?' if cpu is None else f'{cpu:.0f}'} s, "
          f"{b['machine']['cpu_count']} cores, "
          f"load average at the start {load}")
    ok = wall <= budget
    for s, ax in LOADED.items():
        for c, cells in r["summary"].items():
            if s not in cells:
                continue
            t = cells[s]["servo_error_mdeg"][ax]["three_sigma"]
            lo, hi = t["ci95"]
            hw = 50.0 * (hi - lo) / t["value"]
            batched = r["meta"]["batched"].get(c, False)
            judged = c not in NOT_JUDGED and not quick
            verdict = ("ok" if hw <= HALF_WIDTH_PCT else "MISSED") if judged else "(not judged)"
            ok &= hw <= HALF_WIDTH_PCT or not judged
            print(f"  {s} {ax} {c:>9s}: 3σ {t['value']:.4g} mdeg, 95 % CI [{lo:.4g}, {hi:.4g}], "
                  f"half-width {hw:.1f} % ({t['n_episodes']} episodes, "
                  f"{'batched' if batched else 'one at a time'}) {verdict}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
