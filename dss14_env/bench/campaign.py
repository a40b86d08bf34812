"""``dss14 campaign``: how each controller holds up over many plants drawn from the report's
parameter ranges -- a Monte-Carlo robustness campaign in independent, resumable chunks.

The grid is *plants x wind conditions x controllers*:

* **plants** ``first_plant .. first_plant + plants - 1``: plant ``k`` has the hydraulic
  parameters :func:`plant_params` ``(k)`` -- :func:`dss14_env.model.uncertainty.draw_stable_params`
  (log-uniform over the report's ranges, [R] Tables 1-3, stable part only, as the environment's
  ``randomize_params`` draws them) from the generator ``numpy.random.default_rng((k, 0))`` --
  and every episode on it is reset with the seed :func:`episode_seed` ``(k) = k`` (start
  position and gust realisation), the same for every controller and wind condition (common
  random numbers: the controllers are compared on the same gusts);
* **wind conditions**: every mean speed (km/h) x direction (``front``, ``side`` or degrees
  from the boresight), a ``hold`` episode each (the scenario of [R] Table 4);
* **controllers**: rows of :data:`dss14_env.bench.catalog.CONTROLLERS`.  Each is
  built from an environment of the *nominal* plant (same keys, no ``params``) and never sees
  the drawn parameters; each episode is scored by :func:`dss14_env.baselines.rollout.run_episode`,
  exactly as the bench scores it.

The plants are cut into chunks of ``chunk_size`` consecutive plants.  A chunk is one work item
(:func:`run_chunk`) of an executor (:mod:`dss14_env.core.parallel`: in-process, or a Ray task on
a local Ray or a cluster); it builds its own controllers, so its result depends on nothing but
the campaign's options and its plants -- the same numbers in-process, on Ray, in any order,
and after a restart, bit for bit when each process builds the cached model with the executors'
single BLAS thread (as ``dss14 campaign`` does; ``docs/scale.md``).  Each finished chunk is
written at once as JSON (``chunks/chunk-NNNNN.json``, atomically); ``resume=True`` reads the
finished chunks back instead of recomputing them, and refuses a folder whose ``campaign.json``
holds other options.
The statistics, ``results.json``, ``results.md`` and the CDF figures come from all chunks at the
end (:mod:`dss14_env.bench.campaign_report`).

>>> spec = CampaignSpec(controllers=("pi_kp1",), plants=2, wind_speeds_kmh=(50.0,),
...                     directions=("side",), steps=300, chunk_size=1)
>>> [c.key for c in spec.conditions], spec.chunks()
(['50kmh_side'], [[0], [1]])
>>> ep = run_chunk({"spec": spec.as_dict(), "chunk": 0, "plants": [0]})["episodes"][0]
>>> ep["plant"], ep["controller"], ep["condition"], ep["terminated"]
(0, 'pi_kp1', '50kmh_side', False)
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime, timezone
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import campaign_report as report
from dss14_env.bench import runner
from dss14_env.bench.campaign_spec import (  # noqa: F401 - the options, re-exported
    COMMAND,
    DEFAULT_CHUNK_SIZE,
    DEFAULT_CONTROLLERS,
    DEFAULT_DIRECTIONS,
    DEFAULT_PLANTS,
    DEFAULT_STEPS,
    DEFAULT_WIND_SPEEDS_KMH,
    FORMAT,
    OWNED,
    WARMUP_S,
    CampaignOptionError,
    CampaignSpec,
    Condition,
    check_policy,
    check_spec,
    known_controllers,
    parse_directions,
)
from dss14_env.bench.plan import parse_wind_speeds  # noqa: F401 - the option, re-exported
from dss14_env.core.files import read_json
from dss14_env.core.outdir import (
    OutputDirError,
    atomic_write_text,
    manifest_kept,
    prepare_output_dir,
    reopen_output_dir,
    update_manifest,
)
from dss14_env.core.parallel import Executor, SerialExecutor
from dss14_env.core.progress import Progress
from dss14_env.model.assembly import default_model
from dss14_env.model.uncertainty import ParamDraw, draw_params, perturbed_rate_loop, pi_loop_abscissa


# ---------------------------------------------------------------------------- plants
@lru_cache(maxsize=1024)
def _plant_draw(k: int, condition_on_pi: bool) -> ParamDraw:
    return draw_params(np.random.default_rng((k, 0)), condition_on_pi=condition_on_pi)


def plant_draw(k: int, condition_on_pi: bool = True) -> ParamDraw:
    """Plant ``k``'s draw (:func:`dss14_env.model.uncertainty.draw_params` from
    ``numpy.random.default_rng((k, 0))``): its parameters and the draws rejected before them.
    A pure function of its arguments (remembered).
    """
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
        raise ValueError(f"plant index must be a non-negative integer, got {k!r}")
    return _plant_draw(int(k), bool(condition_on_pi))


def plant_params(k: int, condition_on_pi: bool = True) -> dict[str, float]:
    """The hydraulic parameters of plant ``k`` (SI; names of
    :data:`dss14_env.model.uncertainty.SWEEP_PARAMS`): a stable draw over the report's ranges
    from ``numpy.random.default_rng((k, 0))`` (:func:`plant_draw`).
    """
    return dict(sorted(plant_draw(k, condition_on_pi).values.items()))


def plant_record(k: int, condition_on_pi: bool = True) -> dict[str, Any]:
    """What a chunk records of plant ``k``: index, parameters, reset seed, the draws rejected
    before it (by reason) and the report's PI loops' largest pole real part on it (1/s; >= 0:
    that PI is unstable on the plant).
    """
    draw, model = plant_draw(k, condition_on_pi), default_model()
    rl = perturbed_rate_loop(model, dict(draw.values))
    return {"index": k, "params": plant_params(k, condition_on_pi), "episode_seed": episode_seed(k),
            "params_rejected": dict(draw.rejected),
            "pi_loop_abscissa": {g: pi_loop_abscissa(rl, *model.gains(g)) for g in model.cfg.gain_sets}}


def episode_seed(k: int) -> int:
    """The reset seed of every episode on plant ``k``: ``k``."""
    return int(k)


# ---------------------------------------------------------------------------- one chunk
#: per-episode entries of :func:`dss14_env.baselines.rollout.run_episode` a campaign leaves out:
#: wall-clock timings (they differ from run to run) and the limiter's constants
DROPPED_METRICS = ("controller_time_ms", "limits")


def run_chunk(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run one chunk: every plant of it x every condition x every controller.

    :param task: ``{"spec": CampaignSpec.as_dict(), "chunk": index, "plants": [k, ...]}``
    :return: JSON-ready ``{"format", "fingerprint", "chunk", "plants": [{"index", "params",
        "episode_seed", "params_rejected", "pi_loop_abscissa"}], "episodes": [...]}``
        (:func:`plant_record`); each episode is
        :func:`dss14_env.baselines.rollout.run_episode`'s metrics (less :data:`DROPPED_METRICS`)
        plus ``plant``, ``controller``, ``condition``
    """
    from dss14_env.envs.env import DSS14Env

    spec = CampaignSpec.from_dict(task["spec"])
    plants = [int(k) for k in task["plants"]]
    ctrls: dict[tuple[str, str], Any] = {}
    for cond in spec.conditions:  # built on the NOMINAL plant, fresh for every chunk
        nominal = DSS14Env(**cond.env_keys())
        for row in spec.rows():
            ctrls[(row.name, cond.key)] = row.make(nominal)
    episodes = []
    for k in plants:
        params = plant_params(k, spec.condition_on_pi)
        for cond in spec.conditions:
            env = DSS14Env(**cond.env_keys(), params=params)
            for name in spec.names:
                m = runner.run_episode(ctrls[(name, cond.key)], env, episode_seed(k), spec.steps,
                                       spec.warmup_s)
                for key in DROPPED_METRICS:
                    m.pop(key, None)
                m.update({"plant": k, "controller": name, "condition": cond.key})
                episodes.append(m)
    return {"format": FORMAT, "fingerprint": spec.fingerprint(), "chunk": int(task["chunk"]),
            "plants": [plant_record(k, spec.condition_on_pi) for k in plants],
            "episodes": episodes}


# ---------------------------------------------------------------------------- files
class CampaignFileError(ValueError):
    """A campaign or chunk file that cannot be used; the message names the file."""


def chunk_path(out: str | os.PathLike, i: int) -> Path:
    """Where chunk ``i`` of a campaign in ``out`` is written."""
    return Path(out) / "chunks" / f"chunk-{i:05d}.json"


def _read_json(path: Path) -> Any:
    try:
        return read_json(path)
    except (OSError, ValueError) as exc:
        raise CampaignFileError(f"{path}: cannot be read as JSON ({exc})") from None


def read_campaign(out: str | os.PathLike) -> CampaignSpec:
    """The options of the campaign in ``out`` (its ``campaign.json``)."""
    path = Path(out) / "campaign.json"
    d = _read_json(path)
    try:
        return CampaignSpec.from_dict(d["spec"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CampaignFileError(f"{path}: not a campaign file of this version ({exc})") from None


def spec_differences(old: CampaignSpec, new: CampaignSpec) -> list[str]:
    """``"name: old -> new"`` for every option that differs."""
    a, b = old.as_dict(), new.as_dict()
    return [f"{k}: {a[k]!r} -> {b[k]!r}" for k in a if a[k] != b.get(k)]


def load_chunk(path: Path, spec: CampaignSpec, i: int, plants: Sequence[int]) -> dict[str, Any]:
    """A finished chunk read back and checked against the campaign (fingerprint, index, plants
    and number of episodes).

    :raises CampaignFileError: naming the file
    """
    d = _read_json(path)
    want = len(plants) * len(spec.conditions) * len(spec.controllers)
    problems = []
    if not isinstance(d, dict):
        problems.append("not a JSON object")
    else:
        if d.get("fingerprint") != spec.fingerprint():
            problems.append("written by a campaign with other options")
        if d.get("chunk") != i:
            problems.append(f"chunk index {d.get('chunk')!r}, expected {i}")
        if [p.get("index") for p in d.get("plants", [])] != list(plants):
            problems.append(f"plants differ from {list(plants)}")
        if len(d.get("episodes", [])) != want:
            problems.append(f"{len(d.get('episodes', []))} episodes, expected {want}")
    if problems:
        raise CampaignFileError(f"{path}: {'; '.join(problems)} -- remove it to recompute the chunk")
    return d


def finished_chunks(out: str | os.PathLike, spec: CampaignSpec) -> dict[int, dict[str, Any]]:
    """The chunks of ``spec`` already written in ``out``, by index."""
    done = {}
    for i, plants in enumerate(spec.chunks()):
        p = chunk_path(out, i)
        if p.is_file():
            done[i] = load_chunk(p, spec, i, plants)
    return done


def open_campaign(spec: CampaignSpec, out: str | os.PathLike, resume: bool = False,
                  overwrite: bool = False) -> tuple[Path, dict[int, dict[str, Any]]]:
    """Check the output folder before any work and return it with the chunks already done.

    * a new campaign: the folder must hold none of :data:`OWNED` (``overwrite`` removes them,
      :func:`dss14_env.core.outdir.prepare_output_dir`); ``campaign.json`` is written;
    * ``resume`` and a ``campaign.json`` there: its options must equal ``spec`` (else
      :class:`CampaignOptionError` listing the differences); the finished chunks are read back
      (:func:`load_chunk`); ``resume`` in a folder without a campaign starts a new one.

    :raises CampaignOptionError: ``resume`` with ``overwrite``, or other options
    :raises dss14_env.core.outdir.OutputDirError: an unusable folder, or one with results
        and neither ``resume`` nor ``overwrite``
    """
    if resume and overwrite:
        raise CampaignOptionError("--resume and --overwrite: choose one (continue the campaign, or "
                                  "replace it)")
    out = Path(out)
    cj = out / "campaign.json"
    if cj.is_file() and not overwrite:
        if not resume:
            raise OutputDirError(f"output folder {out} already holds a campaign (campaign.json); "
                                 f"pass --resume to continue it, --overwrite to replace it, or "
                                 f"choose another folder")
        old = read_campaign(out)
        if old != spec:
            raise CampaignOptionError(f"--resume: {out} holds a campaign with other options ("
                                      f"{'; '.join(spec_differences(old, spec))}); pass the same "
                                      f"options, --overwrite to replace it, or choose another folder")
        reopen_output_dir(out, OWNED, command=COMMAND)  # still a writable folder; its manifest kept
        (out / "chunks").mkdir(exist_ok=True)
        return out, finished_chunks(out, spec)
    prepare_output_dir(out, OWNED, overwrite=overwrite, command=COMMAND)
    (out / "chunks").mkdir(exist_ok=True)
    atomic_write_text(cj, json.dumps({"format": FORMAT, "spec": spec.as_dict(),
                                      "fingerprint": spec.fingerprint()}, indent=1) + "\n")
    update_manifest(out)
    return out, {}


# ---------------------------------------------------------------------------- the campaign
def _chunk_label(i: int, plants: Sequence[int]) -> str:
    return f"chunk {i} (plants {plants[0]}-{plants[-1]})"


def run_chunks(spec: CampaignSpec, out: Path, done: dict[int, dict[str, Any]], executor: Executor,
               progress: bool = True) -> list[int]:
    """Run the chunks not in ``done`` through ``executor``; write each one as it finishes and
    add it to ``done``.

    :return: the indices of the chunks computed now
    """
    chunks = spec.chunks()
    todo = [i for i in range(len(chunks)) if i not in done]
    tasks = [{"spec": spec.as_dict(), "chunk": i, "plants": chunks[i]} for i in todo]
    labels = [_chunk_label(i, chunks[i]) for i in todo]
    computed = []
    with Progress(len(chunks), f"campaign ({executor.kind})", unit="chunks", enabled=progress,
                  initial=len(done)) as bar:
        for j, res in executor.map_unordered(run_chunk, tasks, labels):
            i = todo[j]
            atomic_write_text(chunk_path(out, i), json.dumps(res) + "\n")
            done[i] = res
            computed.append(i)
            bar.set_note(f"{labels[j]} done")
            bar.update(1)
    return computed


def results_json(results: Mapping[str, Any]) -> str:
    """results.json's text: indented, but one line per plant and per episode (thousands)."""
    head = {k: v for k, v in results.items() if k not in ("plants", "episodes")}
    text = json.dumps(head, indent=1)[:-2]  # without the closing "\n}"
    for key in ("plants", "episodes"):
        rows = ",\n  ".join(json.dumps(r, separators=(",", ":")) for r in results[key])
        text += f',\n "{key}": [\n  {rows}\n ]'
    return text + "\n}\n"


def run_campaign(spec: CampaignSpec, out: str | os.PathLike = "campaign_out",
                 executor: Executor | Callable[[], Executor] | None = None,
                 requirements: Mapping[str, float] | None = None,
                 resume: bool = False, overwrite: bool = False, figures: bool = True,
                 progress: bool = True, command: str | None = None) -> dict[str, Any]:
    """Run (or finish) a campaign and write its results into ``out``.

    :param spec: the options (:class:`CampaignSpec`)
    :param out: output folder
    :param executor: where the chunks run (default: in-process,
        :class:`dss14_env.core.parallel.SerialExecutor`), or a function that makes it: called
        after the output folder was checked (a Ray start is work), and the executor it makes is
        closed at the end
    :param requirements: pointing requirements, name -> 3-sigma in mdeg (default
        :data:`dss14_env.bench.campaign_report.DEFAULT_REQUIREMENTS`); they enter the
        statistics only, so a resumed campaign may use others
    :param resume: continue the campaign in ``out`` (:func:`open_campaign`)
    :param overwrite: replace the campaign in ``out``
    :param figures: draw the CDF figures
    :param progress: the chunks done on stderr (:class:`~dss14_env.core.progress.Progress`: a bar
        on a terminal, lines otherwise)
    :param command: the command line, for the record
    :return: ``results`` (results.json's content), ``markdown`` (results.md), ``table`` (the
        main table), ``figures``, ``computed`` / ``resumed`` (chunk indices), ``out``
    """
    reqs = report.check_requirements(requirements)
    check_policy(spec)
    t0 = time.perf_counter()
    out, done = open_campaign(spec, out, resume=resume, overwrite=overwrite)
    with manifest_kept(out):
        return _run_in(spec, out, done, executor, reqs, figures, progress, command, t0)


def _run_in(spec: CampaignSpec, out: Path, done: dict[int, dict[str, Any]],
            executor: Executor | Callable[[], Executor] | None, reqs: Mapping[str, float],
            figures: bool, progress: bool, command: str | None, t0: float) -> dict[str, Any]:
    """The campaign in its opened folder (:func:`run_campaign`)."""
    resumed = sorted(done)
    owned = executor is None or (callable(executor) and not hasattr(executor, "map_unordered"))
    ex = SerialExecutor() if executor is None else (executor() if owned else executor)
    try:
        computed = run_chunks(spec, out, done, ex, progress=progress)
        description = ex.describe()
    finally:
        if owned:
            ex.close()
    t_run = time.perf_counter() - t0
    chunks = [done[i] for i in range(len(spec.chunks()))]
    plants = [p for c in chunks for p in c["plants"]]
    episodes = [e for c in chunks for e in c["episodes"]]
    results = {
        "campaign": {"command": command, "spec": spec.as_dict(), "fingerprint": spec.fingerprint(),
                     "requirements_mdeg": reqs, "executor": description,
                     "chunks": {"total": len(chunks), "computed": len(computed), "resumed": len(resumed)},
                     "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                     "wall_time_s": {"chunks": t_run},
                     "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count()}},
        "versions": report.package_versions(),
        "summary": report.summarise(spec, episodes, reqs),
        "draws": report.draw_summary(spec, plants, episodes),
        "plants": plants,
        "episodes": episodes,
    }
    figs = report.draw_cdfs(results, out) if figures else []
    results["campaign"]["figures"] = figs
    results["campaign"]["wall_time_s"]["total"] = time.perf_counter() - t0
    md = report.results_markdown(results)
    atomic_write_text(out / "results.json", results_json(results))
    atomic_write_text(out / "results.md", md)
    return {"results": results, "markdown": md, "table": report.main_table(results), "figures": figs,
            "computed": sorted(computed), "resumed": resumed, "out": out}


__all__ = ["DEFAULT_CONTROLLERS", "DEFAULT_DIRECTIONS", "DEFAULT_PLANTS", "DEFAULT_STEPS",
           "DEFAULT_WIND_SPEEDS_KMH", "CampaignFileError", "CampaignOptionError", "CampaignSpec",
           "Condition", "chunk_path", "episode_seed", "finished_chunks", "known_controllers", "load_chunk",
           "open_campaign", "parse_directions", "parse_wind_speeds", "plant_params", "read_campaign",
           "results_json", "run_campaign", "run_chunk", "run_chunks", "spec_differences"]
