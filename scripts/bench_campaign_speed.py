"""Speed-up of ``dss14 campaign`` on a local Ray against the in-process run, and the equality of
their numbers, measured in one run.

Runs the same campaign twice, each as the command in a fresh process, one after the other:
in-process (``dss14 campaign``) and on a local Ray (``dss14 campaign --ray --num-cpus N``).
Each time is the command's whole wall time -- Python start, Ray's start-up, every worker's
model build, the chunks and the statistics -- so the ratio is what a user sees.  Then the two
``results.json`` are compared: the statistics, the plants and every episode's metrics must be
identical (bit for bit: both executors run each chunk with one BLAS thread).  The machine's load
average (``os.getloadavg``) is recorded before and after each run, and the niceness the runs
had: other jobs on the machine take CPU from both runs, more from the Ray run's two workers than
from the in-process run's one (which cannot use more than one core anyway), so the ratio falls
with the load; say what the load was.

Default: the 200-plant campaign of PI, LQG and MPC in 50 km/h front and side wind, 2 CPUs::

    python scripts/bench_campaign_speed.py --out speed_out

Writes ``speed.json`` (times, ratio, loads, equality, the two command lines) into ``--out``,
next to the two campaign folders ``serial/`` and ``ray/``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path


def run(cmd: list[str]) -> dict:
    """Run a command; its wall time and the load averages before and after."""
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-3000:]}")
    return {"command": " ".join(cmd), "wall_time_s": wall, "load_before": list(load0),
            "load_after": list(os.getloadavg()), "stdout_tail": r.stdout[-2500:]}


def numbers(path: Path) -> dict:
    res = json.loads((path / "results.json").read_text())
    return {k: res[k] for k in ("summary", "plants", "episodes")}


def publish(out: Path, dest: Path, doc: Path) -> None:
    """Keep a measured run with the docs: ``campaign_200.json`` (the Ray run's results, per
    episode what the statistics read), ``campaign_speed.json`` (the speed check without the
    commands' output), the CDF figure, and the section between the manual's
    ``campaign-speed`` markers (:func:`dss14_env.bench.campaign_report.docs_section`)."""
    import shutil

    from dss14_env.bench.campaign import results_json
    from dss14_env.bench.campaign_report import compact_results, docs_section

    speed = json.loads((out / "speed.json").read_text())
    speed = {**speed, "runs": {k: {kk: vv for kk, vv in v.items() if kk != "stdout_tail"}
                               for k, v in speed["runs"].items()}}
    res = compact_results(json.loads((out / "ray" / "results.json").read_text()))
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "campaign_200.json").write_text(results_json(res))
    (dest / "campaign_speed.json").write_text(json.dumps(speed, indent=1) + "\n")
    figs = res["campaign"]["figures"]
    shutil.copyfile(out / "ray" / figs[0], dest / f"campaign_{figs[0]}")
    rel = Path(os.path.relpath(dest / f"campaign_{figs[0]}", doc.parent)).as_posix()
    text = doc.read_text()
    a, b = "<!-- campaign-speed:start -->\n", "<!-- campaign-speed:end -->"
    i, j = text.index(a) + len(a), text.index(b)
    doc.write_text(text[:i] + docs_section(res, speed, rel) + "\n" + text[j:])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--plants", type=int, default=200)
    p.add_argument("--steps", type=int, default=None, help="episode length (default: the command's)")
    p.add_argument("--chunk-size", type=int, default=None)
    p.add_argument("--num-cpus", type=int, default=2, help="CPUs of the local Ray (default 2)")
    p.add_argument("--controllers", nargs="+", default=["pi_kp1", "lqg", "mpc"])
    p.add_argument("--out", default="campaign_speed_out")
    p.add_argument("--publish", default=None, metavar="DIR",
                   help="only keep the run in --out with the docs: files into DIR (docs/results), "
                   "the section of docs/scale.md")
    args = p.parse_args()
    out = Path(args.out)
    if args.publish is not None:
        publish(out, Path(args.publish), Path(__file__).resolve().parents[1] / "docs" / "scale.md")
        return 0
    out.mkdir(parents=True, exist_ok=True)
    base = [sys.executable, "-m", "dss14_env.cli", "campaign", "--plants", str(args.plants),
            "--controllers", *args.controllers, "--wind-speeds", "50", "--directions", "front", "side",
            "--no-progress", "--overwrite"]
    if args.steps is not None:
        base += ["--steps", str(args.steps)]
    if args.chunk_size is not None:
        base += ["--chunk-size", str(args.chunk_size)]
    runs = {}
    print(f"load average before: {os.getloadavg()}", flush=True)
    runs["serial"] = run(base + ["--out", str(out / "serial")])
    print(f"serial: {runs['serial']['wall_time_s']:.1f} s", flush=True)
    runs["ray"] = run(base + ["--ray", "--num-cpus", str(args.num_cpus), "--out", str(out / "ray")])
    print(f"ray ({args.num_cpus} CPUs): {runs['ray']['wall_time_s']:.1f} s", flush=True)
    a, b = numbers(out / "serial"), numbers(out / "ray")
    same = a == b
    speedup = runs["serial"]["wall_time_s"] / runs["ray"]["wall_time_s"]
    summary = {"speedup": speedup, "identical_numbers": same, "n_episodes": len(a["episodes"]),
               "runs": runs, "cpu_count": os.cpu_count(), "niceness": os.nice(0),
               "platform": platform.platform()}
    (out / "speed.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"speed-up {speedup:.2f}x (serial {runs['serial']['wall_time_s']:.1f} s, Ray "
          f"{runs['ray']['wall_time_s']:.1f} s); identical numbers: {same} "
          f"({len(a['episodes'])} episodes); load before/after: serial "
          f"{runs['serial']['load_before'][0]:.1f}/{runs['serial']['load_after'][0]:.1f}, Ray "
          f"{runs['ray']['load_before'][0]:.1f}/{runs['ray']['load_after'][0]:.1f}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
