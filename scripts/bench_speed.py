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
revisions (several short sessions on a busy machine; the installed package's revision is the
last commit that changed it).  ``--profile`` also runs each revision once in one process
(``--jobs 1``, no figures) under cProfile and records the calls and cumulative times of the
loads and designs (:data:`PROFILED`), and checks those runs' figures too::

    python scripts/bench_speed.py --before f6c86b5 --runs 0 --profile --append \
        --json docs/results/bench_speed.json
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
    dirs = package_dirs(src / "pyproject.toml")
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


def package_dirs(pyproject: Path) -> dict[str, str]:
    """The package's folders by import name (``[tool.setuptools.package-dir]``)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        sys.exit("reading pyproject.toml needs tomllib: Python 3.11 or later")
    return tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-dir"]


def revision(rev: str) -> str:
    """The short hash of a git revision; for ``HEAD``, of the last commit that changed the
    package (the working tree is what is installed), with ``+changes`` when its files differ
    from that commit.
    """
    git = ["git", "-C", str(REPO)]
    if rev != "HEAD":
        return subprocess.run([*git, "rev-parse", "--short", rev], capture_output=True, text=True,
                              check=True).stdout.strip()
    dirs = sorted(set(package_dirs(REPO / "pyproject.toml").values())) + ["pyproject.toml"]
    short = subprocess.run([*git, "log", "-1", "--format=%h", "--", *dirs], capture_output=True, text=True,
                           check=True).stdout.strip()
    changed = subprocess.run([*git, "diff", "--quiet", "HEAD", "--", *dirs]).returncode
    return f"{short}+changes" if changed else short


#: the functions whose calls and cumulative times ``--profile`` reports: (module file's tail, name)
PROFILED = (("agents/policy.py", "load_policy"), ("model/config.py", "load_model_config"),
            ("envs/config.py", "load_env_config"), ("core/schema.py", "read_config"),
            ("core/schema.py", "load_yaml"), ("baselines/lqg.py", "design_lqg"),
            ("baselines/qp.py", "data_at"), ("baselines/mpc.py", "set_parameters"),
            ("agents/policy.py", "act_batch"), ("model/calibration.py", "calibrate"),
            ("numba/core/dispatcher.py", "_compile_for_args"), ("bench/runner.py", "run"))


def profile_once(args: list[str], out: Path, pythonpath: Path | None, cwd: Path) -> dict[str, Any]:
    """One bench command in one process (``--jobs 1``, no figures) under cProfile: the calls and
    cumulative seconds of :data:`PROFILED` (the profiler's own overhead included).
    """
    import pstats

    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    prof = out.with_suffix(".prof")
    cmd = [sys.executable, "-m", "cProfile", "-o", str(prof), "-m", "dss14_env.cli", "bench", *args,
           "--jobs", "1", "--no-figures", "--out", str(out), "--overwrite", "--no-progress"]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-3000:]}")
    st = pstats.Stats(str(prof)).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}
    found: dict[str, dict[str, float]] = {}
    for tail, name in PROFILED:
        rows = [v for (f, _, n), v in st.items() if n == name and f.replace(os.sep, "/").endswith(tail)]
        found[f"{tail}:{name}"] = {"calls": sum(v[1] for v in rows),
                                   "cumulative_s": round(max((v[3] for v in rows), default=0.0), 2)}
    total = max(v[3] for v in st.values())
    figures = json.dumps(run_figures(json.loads((out / "results.json").read_text())), sort_keys=True)
    return {"total_s": round(total, 2), "functions": found,
            "figures_sha": hashlib.sha256(figures.encode()).hexdigest()}


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
    ap.add_argument("--profile", action="store_true", help="also profile one run of each revision in "
                    "one process (--jobs 1, no figures): calls and cumulative times of the loads")
    a = ap.parse_args(argv)
    if a.runs < 0 or (a.runs == 0 and not (a.profile and a.append)):
        ap.error(f"--runs: at least 1 (0 only to add a --profile to an --append file), got {a.runs}")
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
    profiles: dict[str, Any] = {}
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
        if a.profile:
            profiles = {which: profile_once(bench_args, tmp_path / f"profile_{which}", path, tmp_path)
                        for which, path in (("before", pkg), ("after", None))}
            figures |= {p["figures_sha"] for p in profiles.values()}
            for tag, p in profiles["before"]["functions"].items():
                q = profiles["after"]["functions"][tag]
                print(f"{tag:40s} calls {p['calls']:6d} -> {q['calls']:6d}  "
                      f"cumulative {p['cumulative_s']:7.2f} s -> {q['cumulative_s']:7.2f} s")
    m_before, m_after = medians(runs["before"]), medians(runs["after"])
    doc = {"bench_args": a.bench_args, "before": before_rev, "after": after_rev,
           "median_before": m_before, "median_after": m_after,
           "wall_ratio": round(m_before["wall_time_s"] / m_after["wall_time_s"], 2),
           "cpu_ratio": round(m_before["cpu_time_s"] / m_after["cpu_time_s"], 2),
           "identical_figures": len(figures) == 1, "runs": runs,
           "profile": profiles if a.profile else old.get("profile"), "cpu_count": os.cpu_count(),
           "niceness": os.nice(0), "platform": platform.platform()}
    print(f"median wall {m_before['wall_time_s']:.1f} s -> {m_after['wall_time_s']:.1f} s "
          f"(x{doc['wall_ratio']}), cpu {m_before['cpu_time_s']:.1f} s -> {m_after['cpu_time_s']:.1f} s "
          f"(x{doc['cpu_ratio']}); figures identical: {doc['identical_figures']}")
    if a.json is not None:
        atomic_write_text(a.json, json.dumps(doc, indent=1) + "\n")
    return 0 if doc["identical_figures"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
