"""``dss14 bench``: every controller through the one runner, on the same scenarios and seeds.

:func:`bench` runs a :class:`~dss14_env.bench.plan.BenchPlan` end to end::

    from dss14_env.bench.bench import bench, build_plan
    out = bench(build_plan(controllers=["pi_kp1", "lqg"], quick=True, out="bench_out"))
    print(out["main_table"])

in its own rooms: :mod:`~dss14_env.bench.plan` (options -> validated plan),
:mod:`~dss14_env.bench.run` (the plan through :mod:`~dss14_env.bench.runner`, the one place
that scores every controller the same way), :mod:`~dss14_env.bench.report` (results.json,
results.md, tables), :mod:`~dss14_env.bench.figures` (PNG figures) and
:mod:`~dss14_env.bench.threads` (BLAS threads).  ``docs/bench.md`` describes the options, the
output files and how to read them.
"""

from __future__ import annotations

import math
import resource
import time
from typing import Any

from dss14_env.bench.figures import FIGURES, draw_figures
from dss14_env.bench.plan import (
    DEFAULT_CONTROLLERS,
    DEFAULT_SCENARIOS,
    BenchOptionError,
    BenchPlan,
    build_plan,
    parse_seeds,
    parse_wind_speeds,
)
from dss14_env.bench.report import (
    RESULT_FILES,
    assemble_results,
    fmt,
    headline_table,
    load_average,
    main_table,
    package_versions,
    pointing_table,
    results_markdown,
    write_results,
)
from dss14_env.bench.run import run_plan
from dss14_env.bench.threads import blas_threads
from dss14_env.core.outdir import manifest_kept, prepare_output_dir

#: what the bench owns in its output folder (removed by ``--overwrite``, nothing else)
OWNED_FILES: tuple[str, ...] = RESULT_FILES + FIGURES
#: the command its output folders belong to (their manifest's)
COMMAND = "bench"


def prepare_out(plan: BenchPlan) -> None:
    """Check the output folder before any work: a file in the way, a folder that cannot be
    written, or earlier results without ``overwrite`` raise
    :class:`dss14_env.core.outdir.OutputDirError` (one line naming the path).
    """
    prepare_output_dir(plan.out, OWNED_FILES, overwrite=plan.overwrite, option="--out",
                       command=COMMAND)


class NothingScoredError(RuntimeError):
    """A controller of the bench scored nothing: its results are written, its figures are all
    not estimable (one line naming it).
    """


def unscored_controllers(results: dict[str, Any]) -> list[str]:
    """The controllers of a bench's results none of whose servo 3σ (any scenario, any axis) is
    a finite number.
    """
    def finite(v: Any) -> bool:
        return isinstance(v, (int, float)) and math.isfinite(v)

    return [name for name, cells in results["summary"].items()
            if not any(finite(axis["three_sigma"]["value"]) for cell in cells.values()
                       for axis in cell["servo_error_mdeg"].values())]


def bench(plan: BenchPlan, progress: bool = True) -> dict[str, Any]:
    """Run a plan and write its outputs into ``plan.out``.

    The output folder is checked first (:func:`prepare_out`), before any work; result files
    are written atomically.

    :param plan: the plan (:func:`build_plan`; its ``threads`` sets the BLAS threads)
    :param progress: show the progress bar
    :raises NothingScoredError: after writing the results, when a controller scored nothing
        (:func:`unscored_controllers`)
    :return: ``results`` (results.json's content), ``headline`` (the compact headline table
        with its legend, :func:`~dss14_env.bench.report.headline_table`), ``pointing_table``
        (the dish's true pointing error, Markdown), ``main_table`` (the servo error, Markdown), ``markdown``
        (results.md), ``files`` (paths written), ``figures`` (names), ``wall_time_s``, and
        ``ran`` (:func:`dss14_env.bench.run.run_plan`'s output, with the time histories)
    """
    prepare_out(plan)
    with manifest_kept(plan.out):
        return _bench_in(plan, progress)


def _children_cpu() -> float:
    """CPU time (user and system) of this process's ended and waited-for children, s."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _bench_in(plan: BenchPlan, progress: bool) -> dict[str, Any]:
    """The bench itself, in the checked output folder (:func:`bench`)."""
    t0, c0 = time.perf_counter(), time.process_time() + _children_cpu()
    load0 = load_average()
    with blas_threads(plan.threads) as bt:
        ran = run_plan(plan, progress=progress)
    ran["load_average_start"] = load0
    results = assemble_results(plan, ran, time.perf_counter() - t0)
    results["bench"]["blas_threads"] = bt.record()
    t1 = time.perf_counter()
    figures = draw_figures(results, ran, plan.out) if plan.figures else []
    wall = time.perf_counter() - t0
    results["bench"]["wall_time_s"].update({"figures": time.perf_counter() - t1, "total": wall})
    # CPU time of this process (all its threads) and its worker processes: what the run costs
    # on a quiet machine
    results["bench"]["cpu_time_s"] = time.process_time() + _children_cpu() - c0
    results["bench"]["figures"] = figures
    pj, pm = write_results(results, plan.out)
    unscored = unscored_controllers(results)
    if unscored:
        raise NothingScoredError(f"{', '.join(unscored)}: scored nothing in any scenario (every "
                                 f"episode terminated, failed or left no 3σ to estimate); "
                                 f"{pm} shows what happened")
    return {"results": results, "headline": headline_table(results, str(pm)),
            "pointing_table": pointing_table(results), "main_table": main_table(results),
            "markdown": results_markdown(results), "files": [pj, pm] + [plan.out / f for f in figures],
            "figures": figures, "wall_time_s": wall, "ran": ran}


__all__ = ["BenchOptionError", "BenchPlan", "DEFAULT_CONTROLLERS", "DEFAULT_SCENARIOS",
           "FIGURES", "NothingScoredError", "OWNED_FILES", "bench", "unscored_controllers", "build_plan",
           "parse_seeds",
           "parse_wind_speeds", "prepare_out",
           # re-exported for the campaign (dss14_env.bench.campaign, campaign_report)
           "fmt", "package_versions"]
