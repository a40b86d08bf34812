"""The shipped learned policies on the shipped drive: their default-bench figures beside those of
the drive they were trained on, and which of them need retraining.

The learned policies were trained and selected on the drive shipped before the wind-load
evidence pinned the drive/structure split (docs/model.md section 7, step 5: mu 1.0e-3 kPa*s,
k_a2 7e-4 cm^3, wind loads about 3x weaker at the same Table 4).  Both default bench runs score
them against the report's PI on the same seeds (paired bootstrap 95 % intervals): the committed
run of that drive (``--before``, a results.json) and the run on the shipped drive
(``docs/results/bench_default.json``).  A policy needs retraining when, in a scenario where it
beat the PI before (interval of its ratio below 1), it no longer does on the shipped drive.

    python scripts/rescore_policies.py --before OLD.json   # -> docs/results/rl_rescore.json, render
    python scripts/rescore_policies.py --render            # render the committed file
    python scripts/rescore_policies.py --check             # exit 1 if docs/results/rl_results.md differs
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
AFTER = ROOT / "docs" / "results" / "bench_default.json"
RESULTS = ROOT / "docs" / "results" / "rl_rescore.json"
DOC = ROOT / "docs" / "results" / "rl_results.md"
BLOCK = "rl-rescore"
POLICIES = ("ppo_plain", "ppo_residual_lqg", "ppo_general")
#: (scenario, quantity key of the ratio, axis): the loaded axis' pointing and servo error
CELLS = (("hold_front", "vs_reference_pointing_error_mdeg", "el"),
         ("hold_side", "vs_reference_pointing_error_mdeg", "xel"),
         ("hold_front", "vs_reference", "el"), ("hold_side", "vs_reference", "az"),
         ("track", "vs_reference", "el"), ("slew", "vs_reference", "el"))


def ratios(results: dict, policy: str) -> dict:
    """``scenario quantity axis -> {value, ci95}`` of a policy's ratio to the PI (None: not run)."""
    out = {}
    for scen, key, ax in CELLS:
        cell = results["summary"].get(policy, {}).get(scen, {}).get(key, {}).get(ax)
        out[f"{scen} {'pointing' if 'pointing' in key else 'servo'} {ax}"] = (
            None if cell is None else {"value": cell["value"], "ci95": list(cell["ci95"])})
    return out


def compute(before: dict, after: dict) -> dict:
    """Each policy's ratios before and after and the verdict."""
    rows = {}
    for p in POLICIES:
        b, a = ratios(before, p), ratios(after, p)
        lost = [k for k in a if b[k] is not None and a[k] is not None
                and b[k]["ci95"][1] < 1.0 <= a[k]["ci95"][1]]
        rows[p] = {"before": b, "after": a, "lost": lost, "needs_retraining": bool(lost)}
    return {"what": "shipped learned policies: ratio to the PI on the drive they were trained on and "
                    "on the shipped drive (scripts/rescore_policies.py)",
            "before_command": before["bench"]["command"], "after_command": after["bench"]["command"],
            "rows": rows}


def _fmt(c: dict | None) -> str:
    return "—" if c is None else f"{c['value']:.2f} [{c['ci95'][0]:.2f}, {c['ci95'][1]:.2f}]"


def render(res: dict) -> str:
    """The Markdown table of :func:`compute`'s result."""
    keys = list(next(iter(res["rows"].values()))["after"])
    lines = ["| policy | " + " | ".join(f"{k}: trained drive → shipped drive" for k in keys)
             + " | needs retraining |", "|---" * (len(keys) + 2) + "|"]
    for p, r in res["rows"].items():
        cells = [f"{_fmt(r['before'][k])} → {_fmt(r['after'][k])}" for k in keys]
        verdict = "yes: no longer beats the PI in " + ", ".join(r["lost"]) if r["needs_retraining"] else "no"
        lines.append(f"| {p} | " + " | ".join(cells) + f" | {verdict} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Compute (with ``--before``), render or check."""
    from dss14_env.core.text import add_block_options, render_block

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_block_options(p, "docs/results/rl_results.md",
                      ("--before", "results.json of the default bench on the trained drive: compute, "
                                   "then render"))
    a = p.parse_args(argv)
    if a.before is not None:
        res = compute(json.loads(Path(a.before).read_text(encoding="utf-8")),
                      json.loads(AFTER.read_text(encoding="utf-8")))
        RESULTS.write_text(json.dumps(res, indent=1) + "\n", encoding="utf-8")
    return render_block(DOC, BLOCK, render(json.loads(RESULTS.read_text(encoding="utf-8"))), RESULTS,
                        "python scripts/rescore_policies.py --render", check=a.check)


if __name__ == "__main__":
    sys.exit(main())
