"""Write the README's bench table from the committed default results (or check it).

The table between ``<!-- bench-table:start -->`` and ``<!-- bench-table:end -->`` in
README.md is rendered by :func:`dss14_env.bench.report.readme_table` from
``docs/results/bench_default.json``, the results.json of a default ``dss14 bench`` run::

    dss14 bench --out bench_out && cp bench_out/results.json docs/results/bench_default.json
    python scripts/readme_tables.py            # rewrite the table
    python scripts/readme_tables.py --check    # exit 1 if README.md and the results disagree

``tests/test_bench.py`` runs the check.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from dss14_env.bench.report import readme_table

ROOT = Path(__file__).resolve().parents[1]
START, END = "<!-- bench-table:start -->", "<!-- bench-table:end -->"


def render(readme: str, results: dict) -> str:
    """README text with the table region replaced by the one rendered from ``results``."""
    pattern = re.compile(re.escape(START) + r"\n.*?" + re.escape(END), re.S)
    if not pattern.search(readme):
        raise ValueError(f"README has no {START} ... {END} region")
    return pattern.sub(lambda _: f"{START}\n{readme_table(results)}{END}", readme, count=1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--readme", default=str(ROOT / "README.md"))
    ap.add_argument("--results", default=str(ROOT / "docs" / "results" / "bench_default.json"))
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if the README's table is not the rendered one")
    args = ap.parse_args(argv)
    readme = Path(args.readme)
    try:
        text = readme.read_text()
        new = render(text, json.loads(Path(args.results).read_text()))
    except (OSError, ValueError) as exc:
        print(f"readme_tables: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if new != text:
            print(f"{readme}: the bench table differs from {args.results}; run {Path(__file__).name}",
                  file=sys.stderr)
            return 1
        return 0
    if new != text:
        readme.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
