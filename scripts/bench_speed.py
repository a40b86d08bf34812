"""Speed of ``dss14 bench`` against an earlier revision of the package, and the equality of
their figures, measured in one run.

Runs the same bench command (default ``dss14 bench --quick``) as a fresh process, alternately
on an earlier revision (``--before``, a git revision: its package is unpacked from the
repository into a temporary folder and put first on ``PYTHONPATH``) and on the installed
package, ``--runs`` times each.  Each run's wall time is the whole command's (Python start,
imports, model calibration, the worker pool, the figures); its CPU time is the command's and
its worker processes' (``getrusage`` of the ended children).  The machine's load average is
recorded before and after each run: on a shared machine other jobs take CPU from the runs and
stretch their wall time, so the CPU times and the ratio of medians are the steadier figures;
say what the load was.  Then the runs' ``results.json`` are compared: their figures
(:func:`dss14_env.bench.report.run_figures`: everything but the run's description and
timings) must be identical, bit for bit, across every run of both revisions.

Three runs each of the quick bench (about 4 minutes on 2 cores)::

    python scripts/bench_speed.py --before f6c86b5 --runs 3 --json docs/results/bench_speed.json

``--append`` adds the runs to those of an existing ``--json`` of the same command and
revisions (several short sessions on a busy machine).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from dss14_env.bench.report import run_figures
from dss14_env.core.outdir import atomic_write_text

REPO = Path(__file__).resolve().parent.parent


def unpack_revision(rev: str, dest: Path) -> Path:
    """The package of git revision ``rev`` laid out as installed (the folders of its
    ``[tool.setuptools.package-dir]`` as subpackages) under ``dest``; the folder to put on
    ``PYTHONPATH``.
    """
    src = dest / "src"
    src.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(REPO), "archive", rev], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive.stdout, check=True)
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        sys.exit("unpacking a revision reads its pyproject.toml with tomllib: Python 3.11 or later")
    dirs = tomllib.loads((src / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    pkg = dest / "pkg"
    for name, folder in sorted(dirs.items(), key=lambda kv: kv[0].count(".")):
        shutil.copytree(src / folder, pkg.joinpath(*name.split(".")), dirs_exist_ok=True)
    return pkg


def children_cpu() -> float:
    """CPU time (user and system) of this process's ended children, s."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_once(args: list[str], out: Path, pythonpath: Path | None, cwd: Path) -> dict[str, Any]:
    """One bench command in a fresh process: its wall and CPU time, the load averages, its
    figures.
    """
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    cmd = [sys.executable, "-m", "dss14_env.cli", "bench", *args, "--out", str(out), "--overwrite",
           "--no-progress"]
    load0, c0, t0 = os.getloadavg(), children_cpu(), time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    wall, cpu = time.perf_counter() - t0, children_cpu() - c0
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-3000:]}")
    results = json.loads((out / "results.json").read_text())
    return {"wall_time_s": round(wall, 2), "cpu_time_s": round(cpu, 2),
            "load_before": [round(x, 2) for x in load0], "load_after": [round(x, 2) for x in os.getloadavg()],
            "figures": json.dumps(run_figures(results), sort_keys=True)}


def revision(rev: str) -> str:
    """The short hash of a git revision of the repository (``HEAD`` with ``+changes`` when the
    working tree's tracked files differ from it: the installed package is the working tree).
    """
    short = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", rev], capture_output=True,
                           text=True, check=True).stdout.strip()
    changed = rev == "HEAD" and subprocess.run(["git", "-C", str(REPO), "diff", "--quiet", "HEAD"]).returncode
    return f"{short}+changes" if changed else short


def medians(runs: list[dict[str, Any]]) -> dict[str, float]:
    """Median wall and CPU time of runs, s."""
    return {k: round(statistics.median(r[k] for r in runs), 2) for k in ("wall_time_s", "cpu_time_s")}


def main(argv: list[str] | None = None) -> int:
    """Run the comparison; print it and write ``--json``."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="git revision of the earlier package")
    ap.add_argument("--runs", type=int, default=3, help="runs of each revision (default 3)")
    ap.add_argument("--bench-args", default="--quick", help="the bench's options (default --quick)")
    ap.add_argument("--json", type=Path, help="write the measurement here")
    ap.add_argument("--append", action="store_true", help="add to the runs of an existing --json")
    a = ap.parse_args(argv)
    if a.runs < 1:
        ap.error(f"--runs: at least 1, got {a.runs}")
    bench_args = a.bench_args.split()
    before_rev, after_rev = (revision(r) for r in (a.before, "HEAD"))
    old: dict[str, Any] = {}
    if a.append and a.json is not None and a.json.is_file():
        old = json.loads(a.json.read_text())
        same = (a.bench_args, before_rev, after_rev)
        if (old.get("bench_args"), old.get("before"), old.get("after")) != same:
            sys.exit(f"{a.json}: another command or other revisions; not appended")
    runs: dict[str, list[dict[str, Any]]] = {"before": list(old.get("runs", {}).get("before", [])),
                                             "after": list(old.get("runs", {}).get("after", []))}
    figures = {r["figures_sha"] for k in runs for r in runs[k]}
    with tempfile.TemporaryDirectory(prefix="bench_speed_") as tmp:
        tmp_path = Path(tmp)
        pkg = unpack_revision(a.before, tmp_path / "before")
        for i in range(a.runs):
            for which, path in (("before", pkg), ("after", None)):
                r = run_once(bench_args, tmp_path / f"{which}_{i}", path, tmp_path)
                fig = r.pop("figures")
                r["figures_sha"] = hashlib.sha256(fig.encode()).hexdigest()
                figures.add(r["figures_sha"])
                runs[which].append(r)
                print(f"{which:6s} run {i + 1}: wall {r['wall_time_s']:7.1f} s  cpu {r['cpu_time_s']:7.1f} "
                      f"s  load {r['load_before'][0]:.2f} -> {r['load_after'][0]:.2f}", flush=True)
    m_before, m_after = medians(runs["before"]), medians(runs["after"])
    doc = {"bench_args": a.bench_args, "before": before_rev, "after": after_rev,
           "median_before": m_before, "median_after": m_after,
           "wall_ratio": round(m_before["wall_time_s"] / m_after["wall_time_s"], 2),
           "cpu_ratio": round(m_before["cpu_time_s"] / m_after["cpu_time_s"], 2),
           "identical_figures": len(figures) == 1, "runs": runs, "cpu_count": os.cpu_count(),
           "niceness": os.nice(0), "platform": platform.platform()}
    print(f"median wall {m_before['wall_time_s']:.1f} s -> {m_after['wall_time_s']:.1f} s "
          f"(x{doc['wall_ratio']}), cpu {m_before['cpu_time_s']:.1f} s -> {m_after['cpu_time_s']:.1f} s "
          f"(x{doc['cpu_ratio']}); figures identical: {doc['identical_figures']}")
    if a.json is not None:
        atomic_write_text(a.json, json.dumps(doc, indent=1) + "\n")
    return 0 if doc["identical_figures"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
