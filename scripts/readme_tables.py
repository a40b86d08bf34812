"""Write the README's, docs/bench.md's and the default run's generated tables (or check them).

From ``docs/results/bench_default.json`` (the results.json of a default ``dss14 bench`` run)
and the catalog (:mod:`dss14_env.bench.catalog`):

* every region between ``<!-- NAME:start -->`` and ``<!-- NAME:end -->`` of :data:`REGIONS` in
  README.md and docs/bench.md: the compact headline table
  (:func:`dss14_env.bench.report.headline_table`), the controller and scenario tables;
* the whole of ``docs/results/bench_default.md``, the default run's full tables: the run's
  results.md (:func:`dss14_env.bench.report.results_markdown`)::

    dss14 bench --out bench_out && cp bench_out/results.json docs/results/bench_default.json
    python scripts/readme_tables.py            # rewrite the tables
    python scripts/readme_tables.py --check    # exit 1 if a file and its sources disagree

``tests/test_bench.py`` runs the check.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dss14_env.bench.catalog import controllers_table, scenarios_table
from dss14_env.bench.report import headline_table, results_markdown
from dss14_env.core.text import fill_blocks, find_blocks

ROOT = Path(__file__).resolve().parents[1]
#: the default run's full tables, relative to the repository
FULL_TABLES = "docs/results/bench_default.md"
#: the generated regions by name: their renderer (given the default results)
REGIONS: dict[str, Callable[[Any], str]] = {
    "bench-headline": lambda r: headline_table(r, FULL_TABLES),
    "catalog-controllers": lambda _: controllers_table(),
    "catalog-scenarios": lambda _: scenarios_table(),
}
#: the region every README must have
README_REGION = "bench-headline"


def render(text: str, results: Any, required: tuple[str, ...] = ()) -> str:
    """``text`` with every region of :data:`REGIONS` it has rendered anew
    (:func:`dss14_env.core.text.fill_blocks`).

    :raises ValueError: a region of ``required`` is missing
    """
    present = find_blocks(text)
    for name in required:
        if name not in present:
            raise ValueError(f"no <!-- {name}:start --> ... <!-- {name}:end --> region")
    return fill_blocks(text, {name: fn(results) for name, fn in REGIONS.items() if name in present})


def _default(given: str | None, readme: str | None, path: str) -> str | None:
    """An optional file: the one given, else the repository's when --readme is not given."""
    if given is not None:
        return given or None
    return None if readme else str(ROOT / path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--readme", default=None, help="the README (default: the repository's)")
    ap.add_argument("--bench-doc", default=None,
                    help="the bench's manual (default: the repository's docs/bench.md when --readme "
                    "is not given, else none)")
    ap.add_argument("--full-tables", default=None,
                    help=f"the default run's full tables (default: the repository's {FULL_TABLES} when "
                    "--readme is not given, else none)")
    ap.add_argument("--results", default=str(ROOT / "docs" / "results" / "bench_default.json"))
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if a file's tables are not the rendered ones")
    args = ap.parse_args(argv)
    doc = _default(args.bench_doc, args.readme, "docs/bench.md")
    full = _default(args.full_tables, args.readme, FULL_TABLES)
    status = 0
    try:
        results = json.loads(Path(args.results).read_text())
        # (file, its rendering from its text, whether it is generated whole: may not exist yet)
        files: list[tuple[Path, Callable[[str], str], bool]] = [
            (Path(args.readme or ROOT / "README.md"), lambda t: render(t, results, (README_REGION,)), False)]
        if doc:
            files.append((Path(doc), lambda t: render(t, results), False))
        if full:
            files.append((Path(full), lambda _: results_markdown(results), True))
        for path, rendered, whole in files:
            text = "" if whole and not path.exists() else path.read_text()
            try:
                new = rendered(text)
            except ValueError as exc:
                raise ValueError(f"{path}: {exc}") from None
            if new == text:
                continue
            if args.check:
                print(f"{path}: its tables differ from {args.results} and the catalog; run "
                      f"{Path(__file__).name}", file=sys.stderr)
                status = 1
            else:
                path.write_text(new)
    except (OSError, ValueError) as exc:
        print(f"readme_tables: {exc}", file=sys.stderr)
        return 2
    return status


if __name__ == "__main__":
    sys.exit(main())
