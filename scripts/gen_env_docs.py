"""Write the generated sections of ``docs/env.md``: the manual (the class docstring of
:class:`dss14_env.envs.env.DSS14Env`, the one source), the vector environment (the docstring of
:mod:`dss14_env.envs.vector`) and the speed table (``docs/results/env_speed.json``, written by
``scripts/bench_env_speed.py --json``).

    python scripts/gen_env_docs.py           # rewrite the sections in docs/env.md
    python scripts/gen_env_docs.py --check   # exit 1 if docs/env.md is not up to date

Each section sits between ``<!-- BEGIN generated: NAME ... -->`` and ``<!-- END generated: NAME -->``;
everything outside the markers is written by hand.
"""

from __future__ import annotations

import argparse
import inspect
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
from dss14_env.envs import vector  # noqa: E402
from dss14_env.envs.env import DSS14Env  # noqa: E402

DOC = ROOT / "docs" / "env.md"
SPEED = ROOT / "docs" / "results" / "env_speed.json"


def markdown(doc: str, shift: int = 1) -> str:
    """A docstring as markdown: dedented, reST literals and roles as code, the ``:param:`` block
    dropped, headings ``shift`` levels deeper."""
    text = inspect.cleandoc(doc)
    text = re.split(r"\n:param ", text)[0].rstrip()
    text = re.sub(r":(?:class|func|meth|mod|data|attr):`~?([^`]+)`", r"`\1`", text)
    text = text.replace("``", "`")
    return re.sub(r"^(#+) ", lambda m: "#" * (len(m.group(1)) + shift) + " ", text, flags=re.M)


def manual() -> str:
    """The manual: :class:`DSS14Env`'s docstring."""
    return markdown(DSS14Env.__doc__)


def vector_section() -> str:
    """The vector environment: :mod:`dss14_env.envs.vector`'s docstring."""
    return markdown(vector.__doc__)


def speed_table(path: Path = SPEED) -> str:
    """The speed results of ``scripts/bench_env_speed.py --json`` as a table with their intervals."""
    if not path.is_file():
        return f"(no results yet: run `python scripts/bench_env_speed.py --json {path.relative_to(ROOT)}`)"
    res = json.loads(path.read_text())
    st, m = res["settings"], res["machine"]

    def ci(s: dict, fmt: str) -> str:
        return "" if s["ci95"] is None else f" ({format(s['ci95'][0], fmt)} - {format(s['ci95'][1], fmt)})"

    lines = ["| | steps/s, median (95 % CI) | ratio to Pendulum-v1, median (95 % CI) |", "|---|---|---|"]
    for env_id, s in res["single"].items():
        r = res["ratio_to_pendulum"].get(env_id)
        ratio = "1" if r is None else f"{r['median']:.2f}{ci(r, '.2f')}"
        lines.append(f"| `{env_id}` | {s['median']:,.0f}{ci(s, ',.0f')} | {ratio} |")
    lines += ["", f"| vector env, N = {st['num_envs']} | env-steps/s, median (95 % CI) | raw matmul of "
              "its plant size, rows/s | vector env ÷ raw matmul, median (95 % CI) |", "|---|---|---|---|"]
    for env_id, s in res["vector"].items():
        mm, r = res.get("matmul", {}).get(env_id), res.get("ratio_to_matmul", {}).get(env_id)
        shape = "" if mm is None else " ({0}×{1})·({1}×{2})".format(*mm["shape"])
        lines.append(f"| `{env_id}` | {s['median']:,.0f}{ci(s, ',.0f')} | "
                     + ("—" if mm is None else f"{mm['median']:,.0f}{ci(mm, ',.0f')}{shape}") + " | "
                     + ("—" if r is None else f"{r['median']:.2f}{ci(r, '.2f')}") + " |")
    blas = f", BLAS threads limited to {st['blas_threads']}" if st.get("blas_threads") else ""
    per_repeat = {s.get("steps_per_repeat", st["vec_steps"]) for s in res["vector"].values()}
    vec_steps = " / ".join(f"{n:,}" for n in sorted(per_repeat))
    cycle = " (one episode length: each round holds one autoreset of all)" if st["vec_steps"] is None else ""
    kinds = {s.get("compiled") for s in res["vector"].values()}  # said when one for all ids
    step = {True: ", the vector env's step compiled (numba)", False: ", the vector env's step as numpy "
            "pieces (no numba)"}.get(kinds.pop(), "") if len(kinds) == 1 else ""
    lines += ["", f"Measured {res['when']} with the {st['clock']} clock{blas}, {st['repeats']} rounds of "
              f"{st['steps']:,} single-env and {vec_steps} vector-env steps{cycle}{step}, on {m['cpus']} "
              f"CPUs at load average {m['load_average_1_5_15'][0]:.1f} (Python {m['python']}, "
              f"numpy {m['numpy']}, "
              f"gymnasium {m['gymnasium']}); intervals are bootstrap intervals of the median over the "
              "rounds."]
    return "\n".join(lines)


SECTIONS = {"manual": manual, "vector": vector_section, "speed": speed_table}


def render(text: str) -> str:
    """``text`` (docs/env.md) with every generated section rewritten."""
    for name, build in SECTIONS.items():
        pattern = re.compile(rf"(<!-- BEGIN generated: {name}[^\n]*-->\n)(.*?)"
                             rf"(<!-- END generated: {name} -->)", re.S)
        if not pattern.search(text):
            raise ValueError(f"{DOC}: the markers of the generated section {name!r} are missing")
        text = pattern.sub(lambda m, b=build: m.group(1) + "\n" + b() + "\n\n" + m.group(3), text)
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only check that docs/env.md is up to date")
    args = ap.parse_args()
    old = DOC.read_text()
    new = render(old)
    if args.check:
        if new != old:
            print(f"{DOC} is out of date: run python scripts/gen_env_docs.py", file=sys.stderr)
            return 1
        return 0
    DOC.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
