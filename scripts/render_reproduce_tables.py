"""Render the generated tables of docs/model.md and docs/wind.md.

The tables between ``<!-- NAME:start -->`` and ``<!-- NAME:end -->`` markers are rendered by
:func:`dss14_env.reproduce.doc_blocks` from the committed results file
``docs/results/reproduce_metrics.json``; nothing in them is typed by hand.  Refresh the results
file first when the model changes::

    dss14 reproduce --no-figures --out /tmp/rep
    cp /tmp/rep/metrics.json docs/results/reproduce_metrics.json
    python scripts/render_reproduce_tables.py            # rewrite the documents
    python scripts/render_reproduce_tables.py --check    # exit 1 if a document is out of date

(tests/test_doc_tables.py runs the check.)
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from dss14_env.reproduce import doc_blocks, fill_blocks, find_blocks  # noqa: E402

RESULTS = ROOT / "docs" / "results" / "reproduce_metrics.json"
DOCUMENTS = [ROOT / "docs" / "model.md", ROOT / "docs" / "wind.md"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    parser.add_argument("--results", default=str(RESULTS), help="results file (default: the committed one)")
    args = parser.parse_args(argv)
    blocks = doc_blocks(json.loads(Path(args.results).read_text()))
    stale = []
    for doc in DOCUMENTS:
        text = doc.read_text()
        unknown = {n for n in find_blocks(text) if n.startswith("reproduce-")} - set(blocks)
        if unknown:
            print(f"{doc}: unknown generated block(s) {sorted(unknown)}", file=sys.stderr)
            return 2
        new = fill_blocks(text, blocks)
        if new != text:
            stale.append(doc)
            if not args.check:
                doc.write_text(new)
    verb = "out of date" if args.check else "rewritten"
    for doc in stale:
        print(f"{doc.relative_to(ROOT)}: {verb}")
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
