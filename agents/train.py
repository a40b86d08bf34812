"""Training (stable-baselines3 PPO, sb3-contrib RecurrentPPO, SAC) into one run folder.

:func:`train` writes everything of one run into one folder (default
``runs/<algo>-<timestamp>/``); nothing in it needs unpickling to be read back
(:mod:`dss14_env.agents.storage`)::

    config.yaml                  resolved configuration (every key; loads back with load_config)
    policy.pt, normalization.npz the final policy (the run folder is a policy folder)
    optimizer.pt, counters.json  what resuming from the final policy needs
    checkpoints/<N>_steps/       policy folder + optimizer.pt + counters.json (+ SAC's
                                 replay_buffer.npz) every checkpoint_freq steps
    eval/evaluations.npz         every periodic evaluation (validation seeds)
    eval/best/                   policy folder of the best evaluation so far
    tb/                          TensorBoard event files (if tensorboard is installed)
    monitor/                     training episode CSVs (SB3 Monitor / VecMonitor)
    train_summary.json           timesteps, wall time, throughput, run id, versions

A new run refuses a folder that already holds a run (finished or interrupted) unless
``overwrite`` (which removes exactly what training owns there); an ``--out`` that is a file
or cannot be written fails before any work.  Ctrl-C (SIGINT) or SIGTERM stops the run at the
next environment step with a checkpoint of that step and raises :class:`TrainingInterrupted`
naming it and the command that resumes from it; a validation round under way ends after its
current task, unrecorded, and a stopped run gets no final validation.  The run's steps show
on stderr as it trains (:mod:`dss14_env.agents.train_control`).
"""

from __future__ import annotations

import json
import math
import re
import shlex
import signal
import time
from collections.abc import Callable, Mapping
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dss14_env.agents.algos import algo_class, algo_kwargs, is_recurrent, policy_kwargs
from dss14_env.agents.config import MAX_TIMESTEPS, TrainConfig, as_config, is_known_env_module, load_config
from dss14_env.agents.envs import (
    EnvPlan,
    check_env,
    make_train_vec_env,
    monitor_files,
    resolve_env,
    vec_env_kind,
)
from dss14_env.agents.evaluation import (
    DEFAULT_SCENARIOS,
    DSS14_TASKS,
    EvalTask,
    check_seed_protocol,
    dss14_tasks,
    run_task,
)
from dss14_env.agents.policy import PolicyController
from dss14_env.agents.storage import (
    CONFIG,
    COUNTERS,
    OPTIMIZER,
    REPLAY,
    STATS,
    WEIGHTS,
    NormStats,
    PolicyFileError,
    check_fingerprints,
    find_policy_files,
    load_optimizers,
    load_replay_buffer,
    load_sb3_model,
    load_stats,
    load_weights,
    new_run_id,
    save_optimizers,
    save_replay_buffer,
    write_policy_folder,
)
from dss14_env.agents.train_control import progress_callback, stop_callback
from dss14_env.core.arrays import read_arrays
from dss14_env.core.outdir import (
    atomic_folder,
    atomic_write_bytes,
    atomic_write_text,
    manifest_kept,
    prepare_output_dir,
    record_files,
    reopen_output_dir,
    update_manifest,
)
from dss14_env.core.schema import config_label
from dss14_env.core.stop import Stopped, StopRequests, signal_name

#: what a training run owns in its folder (removed by ``overwrite``)
#: the command a run folder belongs to (its manifest's)
COMMAND = "train"
RUN_FILES = (CONFIG, WEIGHTS, STATS, OPTIMIZER, COUNTERS, REPLAY, "return_normalization.npz",
             "checkpoints", "eval", "tb",
             "monitor", "train_summary.json", "model.zip", "vecnormalize.pkl")
_CKPT_RE = re.compile(r"^(?P<steps>\d+)_steps$")


class TrainingInterrupted(Stopped):
    """A training stopped by Ctrl-C (SIGINT) or SIGTERM; :attr:`message` is one line naming the
    checkpoint kept and the command that resumes from it.

    :param run: the run folder
    :param steps: environment steps done
    :param checkpoint: the checkpoint folder kept (saved on the stop, or the last periodic one),
        or None
    :param command: the command that resumes from it, or None
    :param signum: the signal that stopped it
    """

    def __init__(self, run: Path, steps: int, checkpoint: Path | None, command: str | None,
                 signum: int = signal.SIGINT) -> None:
        self.run, self.steps, self.checkpoint, self.command = run, steps, checkpoint, command
        head = f"training stopped ({signal_name(signum)}) at {steps} steps"
        if checkpoint is not None:
            self.message = f"{head}; kept checkpoint {checkpoint}; resume with: {command}"
        else:
            self.message = (f"{head}; no checkpoint was written (stopped at once); start again "
                            f"with: {command}")
        super().__init__(signum, self.message)


# ------------------------------------------------------------------------------ resume sources
#: the largest counters file read, bytes (the tool writes some 100)
MAX_COUNTERS_BYTES = 4096
#: a run id as :func:`~dss14_env.agents.storage.new_run_id` makes it
_RUN_ID_RE = re.compile(r"^[0-9a-f]{1,64}$")


def read_counters(path: Path) -> tuple[int, str]:
    """A checkpoint's ``counters.json``, checked like a configuration: ``num_timesteps`` an
    integer in [1, :data:`~dss14_env.agents.config.MAX_TIMESTEPS`] (and, in ``checkpoints/``,
    the step count in the folder's name ``<N>_steps``), ``run_id`` a run id, ``episode_num`` an integer >= 0.

    :return: ``(num_timesteps, run_id)``
    :raises PolicyFileError: one line naming the file and the field
    """
    try:
        if path.stat().st_size > MAX_COUNTERS_BYTES:
            raise ValueError(f"more than {MAX_COUNTERS_BYTES} bytes")
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PolicyFileError(f"{path}: not a readable counters file ({exc})") from None
    if not isinstance(data, dict):
        raise PolicyFileError(f"{path}: not a readable counters file (not a mapping)")

    def count(key: str, lo: int, required: bool = True) -> int:
        v = data.get(key, None if required else lo)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= MAX_TIMESTEPS:
            raise PolicyFileError(f"{path}: field '{key}': must be an integer in [{lo}, "
                                  f"{MAX_TIMESTEPS}], got {v!r}")
        return v

    steps = count("num_timesteps", 1)
    count("episode_num", 0, required=False)
    run_id = data.get("run_id")
    if not isinstance(run_id, str) or not _RUN_ID_RE.match(run_id):
        raise PolicyFileError(f"{path}: field 'run_id': must be a run id (hex digits), got {run_id!r}")
    named = _CKPT_RE.match(path.parent.name) if path.parent.parent.name == "checkpoints" else None
    if named and int(named["steps"]) != steps:
        raise PolicyFileError(f"{path}: field 'num_timesteps': {steps}, the folder's name says "
                              f"{named['steps']}; a checkpoint holds the counters of its own step")
    return steps, run_id


class _Resume:
    """What a run resumes from: a checkpoint folder (safe) or a foreign SB3 zip (opt-in)."""

    def __init__(self, path: Path, trust_pickle: bool) -> None:
        self.path = path
        self.files = find_policy_files(path)
        self.foreign = self.files.foreign
        if self.foreign:
            if not trust_pickle:
                from dss14_env.agents.storage import refuse_pickle_message

                raise PolicyFileError(refuse_pickle_message(self.files.sb3_zip))
            self.steps = -1  # read on load
            self.run_id = new_run_id()
        else:
            folder = self.files.folder
            for f in (OPTIMIZER, COUNTERS):
                if not (folder / f).is_file():
                    raise PolicyFileError(f"{folder}: not a training checkpoint ({f} is missing)")
            self.steps, self.run_id = read_counters(folder / COUNTERS)
            self.fingerprint, self.state = load_weights(folder / WEIGHTS)
            self.optim, self.tensors = load_optimizers(folder / OPTIMIZER)
            self.stats = self._checked_stats(folder)
            if self.fingerprint.get("run_id") != self.run_id:
                raise PolicyFileError(f"{folder / WEIGHTS}: weights of run "
                                      f"{self.fingerprint.get('run_id')!r}, {COUNTERS} says "
                                      f"{self.run_id!r}; a checkpoint holds the files of one run")

    def _checked_stats(self, folder: Path) -> NormStats | None:
        """The checkpoint's normalisation statistics, checked against its weights' fingerprint
        (another run's file, or one of another observation size, is refused).
        """
        stats_file = folder / (STATS if (folder / STATS).is_file() else "return_normalization.npz")
        if not stats_file.is_file():
            return None
        sfp, stats = load_stats(stats_file)
        check_fingerprints(folder / WEIGHTS, self.fingerprint, stats_file, sfp)
        if stats.obs_mean.size != int(self.fingerprint["obs_dim"]):
            raise PolicyFileError(f"{stats_file}: statistics of {stats.obs_mean.size} "
                                  f"observations, the weights expect {self.fingerprint['obs_dim']}")
        return stats

    def check_spaces(self, obs_space: Any, act_space: Any) -> None:
        """Refuse a checkpoint of other observation or action sizes than the configuration's
        environment (before any folder is touched).
        """
        want = (int(np.prod(obs_space.shape)), int(np.prod(act_space.shape)))
        got = (int(self.fingerprint["obs_dim"]), int(self.fingerprint["act_dim"]))
        if want != got:
            raise PolicyFileError(f"{self.files.folder / WEIGHTS}: a policy of {got[0]} "
                                  f"observations and {got[1]} actions; the configuration's "
                                  f"environment has {want[0]} and {want[1]}")

    @property
    def run_folder(self) -> Path:
        """The run folder the checkpoint belongs to."""
        f = self.files.folder if not self.foreign else self.files.sb3_zip.parent
        return f.parent.parent if f.parent.name == "checkpoints" else f


def resume_config_path(resume: str | Path) -> Path | None:
    """The ``config.yaml`` a resume source carries (checkpoint folder or its run), or None."""
    p = Path(resume)
    for cand in (p / CONFIG, p.parent / CONFIG, p.parent.parent / CONFIG):
        if cand.is_file():
            return cand
    return None


# ------------------------------------------------------------------------------ helpers
def _new_run_dir(algo: str, root: Path = Path("runs")) -> Path:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    run = root / f"{algo}-{stamp}"
    i = 1
    while run.exists():
        i += 1
        run = root / f"{algo}-{stamp}-{i}"
    return run


def _installed(*modules: str) -> bool:
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in modules)


def _config_text(cfg: TrainConfig, run_id: str) -> str:
    return (f"# resolved {cfg.algo} configuration of run {run_id} (from {config_label(cfg.source)})\n"
            + yaml.safe_dump(cfg.to_dict(), sort_keys=False))


def _fingerprint(cfg: TrainConfig, run_id: str, model: Any) -> dict[str, Any]:
    space = model.action_space
    return {"algo": cfg.algo, "run_id": run_id,
            "obs_dim": int(np.prod(model.observation_space.shape)),
            "act_dim": int(np.prod(space.shape)),
            "action_low": [float(x) for x in np.ravel(space.low)],
            "action_high": [float(x) for x in np.ravel(space.high)],
            "num_timesteps": int(model.num_timesteps)}


def _stats(cfg: TrainConfig, venv: Any) -> NormStats | None:
    return NormStats.from_vec_normalize(venv) if cfg.normalize_obs else None


def save_checkpoint(folder: Path, cfg: TrainConfig, run_id: str, model: Any, venv: Any,
                    config_text: str) -> None:
    """A resumable policy folder: weights, statistics, config, optimisers, counters."""
    fp = _fingerprint(cfg, run_id, model)
    stats = NormStats.from_vec_normalize(venv)  # return statistics too, for resuming
    write_policy_folder(folder, model.policy, stats if cfg.normalize_obs else None, fp, config_text)
    if not cfg.normalize_obs:  # return statistics still matter when only rewards are normalised
        from dss14_env.agents.storage import save_stats

        save_stats(folder / "return_normalization.npz", stats, fp)
    save_optimizers(folder / OPTIMIZER, model)
    if cfg.algo == "sac" and cfg.save_replay_buffer and getattr(model, "replay_buffer", None) is not None:
        save_replay_buffer(folder / REPLAY, model.replay_buffer)
    atomic_write_text(folder / COUNTERS, json.dumps(
        {"num_timesteps": int(model.num_timesteps), "run_id": run_id,
         "episode_num": int(getattr(model, "_episode_num", 0))}, indent=2) + "\n")


#: what a vector environment's call raises once its subprocess workers are gone
WORKERS_GONE = (EOFError, BrokenPipeError, ConnectionResetError)


def _stop_checkpoint(cfg: TrainConfig, run: Path, run_id: str, model: Any, venv: Any,
                     config_text: str) -> Path:
    """The checkpoint of a run stopped by a signal, at its step count (``checkpoints/<N>_steps``;
    the periodic one when it was just written at that count).
    """
    folder = run / "checkpoints" / f"{int(model.num_timesteps)}_steps"
    if not (folder / COUNTERS).is_file():
        with atomic_folder(folder) as tmp:  # the whole folder, or none of it
            save_checkpoint(tmp, cfg, run_id, model, venv, config_text)
        update_manifest(run)
    return folder


def _restore(model: Any, venv: Any, src: _Resume, cfg: TrainConfig) -> int:
    """Load a resume source into a freshly built model and VecNormalize; its step count."""
    if src.foreign:
        old, vn = load_sb3_model(src.files, algo_class(cfg.algo), True)
        try:
            model.set_parameters(old.get_parameters(), exact_match=True)
        except (ValueError, RuntimeError) as exc:
            raise ValueError(f"{cfg.source}: keys 'net_arch'/'activation_fn'/'log_std_init' do "
                             f"not match checkpoint {src.path}: {str(exc)[:160]}") from None
        if vn is not None:
            NormStats.from_vec_normalize(vn).apply_to(venv)
        return int(old.num_timesteps)
    folder = src.files.folder
    state, optim, tensors = src.state, src.optim, src.tensors
    try:
        model.set_parameters({"policy": state, **optim}, exact_match=True)
    except (ValueError, RuntimeError, KeyError) as exc:
        raise ValueError(f"{cfg.source}: keys 'net_arch'/'activation_fn'/'log_std_init' do not "
                         f"match checkpoint {folder}: {str(exc).splitlines()[0][:160]}") from None
    if "log_ent_coef" in tensors and getattr(model, "log_ent_coef", None) is not None:
        import torch

        with torch.no_grad():
            model.log_ent_coef.copy_(tensors["log_ent_coef"])
    if src.stats is not None:
        src.stats.apply_to(venv)
    if (folder / REPLAY).is_file() and getattr(model, "replay_buffer", None) is not None:
        load_replay_buffer(folder / REPLAY, model.replay_buffer)
    return src.steps


def validation_tasks(cfg: TrainConfig, plan: EnvPlan | None = None) -> list[EvalTask]:
    """The periodic evaluation's tasks: the DSS14 scenarios ``eval_scenarios`` (default the two
    holds, with ``eval_env_kwargs`` laid over), or the configured environment.

    :param plan: the configuration's environment plan (default: resolved from ``cfg``)
    """
    plan = resolve_env(cfg) if plan is None else plan
    if plan.dss14:
        if tuple(cfg.eval_scenarios) != DEFAULT_SCENARIOS:
            return dss14_tasks(cfg.eval_env_kwargs, cfg.eval_scenarios)
        return dss14_tasks(cfg.eval_env_kwargs) if cfg.eval_env_kwargs else list(DSS14_TASKS)
    return [EvalTask("eval", cfg.env_id, {**cfg.env_kwargs, **cfg.eval_env_kwargs})]


# ------------------------------------------------------------------------------ callbacks
def _checkpoint_callback(cfg: TrainConfig, run: Path, run_id: str, config_text: str, venv: Any,
                         start: int, ckpts: list[Path]) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        """A resumable checkpoint folder every ``checkpoint_freq`` environment steps."""

        def __init__(self) -> None:
            super().__init__()
            self.next = (start // cfg.checkpoint_freq + 1) * cfg.checkpoint_freq

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                folder = run / "checkpoints" / f"{self.num_timesteps}_steps"
                with atomic_folder(folder) as tmp:  # the whole folder, or none of it
                    save_checkpoint(tmp, cfg, run_id, self.model, venv, config_text)
                ckpts.append(folder)
                update_manifest(run)
                self.next = (self.num_timesteps // cfg.checkpoint_freq + 1) * cfg.checkpoint_freq
            return True

    return Checkpoints()


def selection_score(cfg: TrainConfig, returns: np.ndarray,
                    three_sigma: Mapping[str, np.ndarray] | None = None,
                    terminated: bool = False) -> float:
    """The validation score that picks ``eval/best`` (higher is better).

    ``select_by: return``: the mean validation return.  ``select_by: three_sigma``: minus the
    geometric mean over the hold tasks of each task's mean 3σ over the validation seeds (the
    test metric; the geometric mean weighs the front and side holds alike though their 3σ
    differ in size); ``-inf`` when a validation episode terminated or a 3σ is not finite.
    ``select_by: pointing``: the same of the 3σ pointing errors (the caller passes those).
    ``select_by: general``: the same over every validation scenario of its
    :func:`general_figure` (the caller passes those).

    :param returns: every validation episode's return
    :param three_sigma: task name -> the validation episodes' 3σ (mdeg) of the selection's
        error (:func:`selection_key`)
    :param terminated: a validation episode terminated
    """
    if cfg.select_by == "return":
        return float(np.mean(returns))
    means = [float(np.mean(v)) for v in (three_sigma or {}).values()]
    if terminated or not means or not all(np.isfinite(m) and m > 0 for m in means):
        return -np.inf
    return -float(np.exp(np.mean(np.log(means))))


def general_figure(task: EvalTask, result: Mapping[str, np.ndarray]) -> np.ndarray:
    """Each validation episode's figure of one scenario for ``select_by: general`` (mdeg or s,
    lower is better): a hold's 3σ servo error on its loaded axis; the step's 2 % settling time
    of the slower axis (inf: never settles); otherwise (track, slew) the larger of the two
    axes' 3σ servo errors -- the worse axis, as the results tables report them (a mean of both
    would reward an unloaded axis' error below one encoder count, which is not a property of
    the controller).
    """
    if task.axis is not None:
        return np.asarray(result["three_sigma_mdeg"], float)
    if task.preset == "step":
        return np.maximum(result["settling_time_s_az"], result["settling_time_s_el"])
    return np.maximum(np.asarray(result["servo_three_sigma_mdeg_az"], float),
                      result["servo_three_sigma_mdeg_el"])


def selection_key(cfg: TrainConfig) -> str:
    """The run-task result (and, with ``_<task>``, the history entry) a 3σ selection scores:
    ``three_sigma_mdeg`` (servo error) or ``pointing_three_sigma_mdeg`` (``select_by: pointing``).
    """
    return "pointing_three_sigma_mdeg" if cfg.select_by == "pointing" else "three_sigma_mdeg"


def selection_figures(cfg: TrainConfig, tasks: list[EvalTask], res: Mapping[str, Mapping[str, Any]]
                      ) -> dict[str, np.ndarray]:
    """The per-episode figures a 3σ, pointing or general selection scores, by task name
    (:func:`general_figure` for every task, else the holds' :func:`selection_key` figure).
    """
    if cfg.select_by == "general":
        return {t.name: general_figure(t, res[t.name]) for t in tasks}
    key = selection_key(cfg)
    return {t.name: np.asarray(res[t.name][key], float) for t in tasks if t.axis is not None}


def reference_figures(cfg: TrainConfig, tasks: list[EvalTask]) -> dict[str, float]:
    """``select_reference``'s mean :func:`selection_figures` per validation task: the same
    seeds, lengths and episodes as the policy's evaluations, the controller built per task on
    its environment (as the bench builds it).
    """
    from dss14_env.agents.campaign_report import reference_runs

    res = reference_runs(cfg.select_reference, tasks, cfg.eval_seeds, cfg.eval_episode_steps,
                         cfg.n_eval_episodes)
    return {k: float(np.mean(v)) for k, v in selection_figures(cfg, tasks, res).items()}


def evaluation_ranks(scores: Any, qualified: Any = None) -> list[tuple[bool, float]]:
    """Each evaluation's rank ``(qualified, selection score)``: ``eval/best`` holds the highest
    (the first of equal ranks).  Without the ``qualified`` flags (a history written before
    them) an evaluation qualifies where its score is finite, as one recorded without a
    reference.
    """
    s = [float(v) for v in scores]
    q = [bool(v) for v in qualified] if qualified is not None else [math.isfinite(v) for v in s]
    return list(zip(q, s, strict=True))


def beats_reference(figures: Mapping[str, np.ndarray], reference: Mapping[str, float]) -> bool:
    """Whether the mean of every task's figures is below the reference's (lower is better; a
    non-finite mean never is).
    """
    return all(bool(np.mean(figures[k]) < v) for k, v in reference.items())


class _Evaluator:
    """The periodic evaluation: the deterministic policy on the validation seeds; keeps
    ``eval/best`` and ``eval/evaluations.npz``.  ``eval/best`` is the evaluation with the best
    :func:`selection_score` among those that beat ``select_reference`` on every validation task
    (:func:`beats_reference`; ``selection_qualified`` in the history), or among all while none
    does (no reference: every evaluation with a finite score qualifies).
    """

    def __init__(self, cfg: TrainConfig, plan: EnvPlan, run: Path, run_id: str, config_text: str,
                 venv: Any, start: int, stopped: Callable[[], bool] = lambda: False) -> None:
        self.cfg, self.plan, self.run, self.run_id = cfg, plan, run, run_id
        #: true once a stop is asked for: a round not yet begun is not begun, one under way ends
        #: after its current task and is not recorded (a stop acts within one task's episodes)
        self.stopped = stopped
        self.config_text, self.venv = config_text, venv
        self.tasks = validation_tasks(cfg, plan)
        if cfg.select_by != "return" and not any(t.axis for t in self.tasks):
            raise ValueError(f"{cfg.source}: key 'select_by': {cfg.select_by} needs DSS14 hold "
                             f"tasks, {cfg.env_id!r} has none (use return)")
        key = selection_key(cfg)
        h = self.history = _load_history(run / "eval" / "evaluations.npz", start)
        if "selection_score" not in h:  # a history written before the score was recorded
            h["selection_score"] = [
                selection_score(cfg, r, {t.name: h[f"{key}_{t.name}"][i] for t in self.tasks
                                         if f"{key}_{t.name}" in h})
                for i, r in enumerate(h["results"])]
        if "selection_qualified" not in h:  # a history written before the flags
            h["selection_qualified"] = [q for q, _ in evaluation_ranks(h["selection_score"])]
        #: ``select_reference``'s mean figure per validation task (None: no reference)
        self.reference = reference_figures(cfg, self.tasks) if cfg.select_reference else None
        self.best = max(evaluation_ranks(h["selection_score"], h["selection_qualified"]),
                        default=(False, -np.inf))
        self.ctrl: PolicyController | None = None

    def __call__(self, model: Any, logger: Any) -> None:
        cfg = self.cfg
        if self.ctrl is None:
            self.ctrl = PolicyController(model.policy, cfg, None, "eval", None, None)
        self.ctrl.stats = _stats(cfg, self.venv)
        steps = cfg.eval_episode_steps if self.plan.dss14 else None
        res = {}
        for t in self.tasks:
            if self.stopped():
                return
            res[t.name] = run_task(self.ctrl, t, cfg.eval_seeds, steps if t.axis is not None else None,
                                   cfg.n_eval_episodes)
        if self.stopped():
            return
        h = self.history
        h["timesteps"].append(int(model.num_timesteps))
        h["results"].append(np.concatenate([r["returns"] for r in res.values()]))
        h["ep_lengths"].append(np.concatenate([r["lengths"] for r in res.values()]))
        for t in self.tasks:
            h.setdefault(f"returns_{t.name}", []).append(res[t.name]["returns"])
            if t.axis is not None:
                h.setdefault(f"three_sigma_mdeg_{t.name}", []).append(res[t.name]["three_sigma_mdeg"])
            if t.pointing_axis is not None:
                h.setdefault(f"pointing_three_sigma_mdeg_{t.name}", []).append(
                    res[t.name]["pointing_three_sigma_mdeg"])
        mean = float(np.mean(h["results"][-1]))
        figures = selection_figures(cfg, self.tasks, res)
        score = selection_score(cfg, h["results"][-1], figures,
                                any(bool(r["terminated"].any()) for r in res.values()))
        qualified = bool(np.isfinite(score)) and (self.reference is None
                                                  or beats_reference(figures, self.reference))
        h["selection_score"].append(score)
        h["selection_qualified"].append(qualified)
        _save_history(self.run / "eval" / "evaluations.npz", h)
        logger.record("eval/mean_return", mean)
        sig = {n: float(np.nanmean(r["three_sigma_mdeg"])) for n, r in res.items()
               if np.isfinite(r["three_sigma_mdeg"]).any()}
        for n, v in sig.items():
            logger.record(f"eval/three_sigma_mdeg_{n}", v)
        for n, r in res.items():
            if np.isfinite(r["pointing_three_sigma_mdeg"]).any():
                logger.record(f"eval/pointing_three_sigma_mdeg_{n}",
                              float(np.nanmean(r["pointing_three_sigma_mdeg"])))
        if (qualified, score) > self.best:
            self.best = (qualified, score)
            with atomic_folder(self.run / "eval" / "best") as tmp:
                write_policy_folder(tmp, model.policy, _stats(cfg, self.venv),
                                    _fingerprint(cfg, self.run_id, model), self.config_text)
        update_manifest(self.run)
        if cfg.verbose:
            print(f"eval at {model.num_timesteps} steps: mean return {mean:.4g}"
                  + "".join(f", {n} 3-sigma {v:.3g} mdeg" for n, v in sig.items()))


def _eval_callback(evaluator: _Evaluator, every: int, start: int) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class PeriodicEvaluation(BaseCallback):
        """Calls the evaluator every ``every`` environment steps."""

        def __init__(self) -> None:
            super().__init__()
            self.next = (start // every + 1) * every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next = (self.num_timesteps // every + 1) * every
                evaluator(self.model, self.logger)
            return True

        def _on_training_end(self) -> None:
            """A final evaluation unless the last one was at the end: a budget shorter than
            ``eval_freq`` still gets ``eval/best`` and ``eval/evaluations.npz``.
            """
            done = evaluator.history["timesteps"]
            if evaluator.stopped():  # a stopped run is not scored on its way out
                return
            if not done or done[-1] != self.num_timesteps:
                evaluator(self.model, self.logger)

    return PeriodicEvaluation()


def _callbacks(cfg: TrainConfig, plan: EnvPlan, run: Path, run_id: str, config_text: str,
               venv: Any, start: int, ckpts: list[Path], requests: StopRequests) -> list[Any]:
    out: list[Any] = [_tensorboard_folder_callback(run)]
    if cfg.checkpoint_freq > 0:
        out.append(_checkpoint_callback(cfg, run, run_id, config_text, venv, start, ckpts))
    if cfg.eval_freq > 0:
        ev = _Evaluator(cfg, plan, run, run_id, config_text, venv, start,
                        stopped=lambda: requests.signum is not None)
        out.append(_eval_callback(ev, cfg.eval_freq, start))
    return out


def _tensorboard_folder_callback(run: Path) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class TensorBoardFolder(BaseCallback):
        """Lists the run's TensorBoard folder (``tb/<ALGO>_<n>``, which stable-baselines3 makes
        for the run) in the run's manifest when training starts.
        """

        def _on_training_start(self) -> None:
            folder = self.logger.get_dir()
            if folder is not None and Path(folder).parent.resolve() == (run / "tb").resolve():
                record_files([Path(folder)], folders=True)

        def _on_step(self) -> bool:
            return True

    return TensorBoardFolder()


def _load_history(path: Path, start: int) -> dict[str, list]:
    """The evaluation history of a run up to ``start`` steps (resume), or an empty one."""
    h: dict[str, list] = {"timesteps": [], "results": [], "ep_lengths": []}
    if start <= 0 or not path.is_file():
        return h
    d = read_arrays(path)
    keep = d["timesteps"] <= start
    for k in d:
        h[k] = [x for x in d[k][keep]]
    h["timesteps"] = [int(t) for t in h["timesteps"]]
    return h


def _save_history(path: Path, h: dict[str, list]) -> None:
    import io

    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    np.savez(buf, **{k: np.asarray(v) for k, v in h.items()})
    atomic_write_bytes(path, buf.getvalue())


def _resume_command(cfg: TrainConfig, run: Path, ckpt: Path | None) -> str:
    """The command that continues an interrupted run: from its last checkpoint, or (none
    written yet) from the start, replacing the run's files.
    """
    cmd = ["dss14", "train", cfg.algo, "--config", str(run / CONFIG)]
    cmd += ["--resume", str(ckpt)] if ckpt is not None else ["--overwrite"]
    if cfg.env_module is not None and not is_known_env_module(cfg.env_module):
        cmd += ["--env-module", cfg.env_module]
    return shlex.join([*cmd, "--out", str(run)])


# ------------------------------------------------------------------------------ training
def prepare_run(cfg: TrainConfig, run_dir: str | Path | None, resume: str | Path | _Resume | None,
                overwrite: bool = False, trust_pickle: bool = False) -> tuple[Path, Any]:
    """The run folder (checked, created) and the resume source, before any work.

    A resume in the checkpoint's own run folder continues there (its files are kept; the
    checkpoints past the resume point are removed only once the model is restored).

    :raises ValueError: an unusable folder (one line, naming it), a folder holding another run
        without ``overwrite``, a missing or refused resume source
    """
    src = resume if isinstance(resume, _Resume) else resume_source(resume, trust_pickle)
    if run_dir is not None:
        run = Path(run_dir)
    elif src is not None:
        run = src.run_folder
    else:
        run = _new_run_dir(cfg.algo)
    if src is not None and run.resolve() == src.run_folder.resolve():
        reopen_output_dir(run, RUN_FILES, option="--out", command=COMMAND)  # continue the run in place
    else:
        prepare_output_dir(run, owned=RUN_FILES, overwrite=overwrite, option="--out", command=COMMAND)
    return run, src


def check_run_first(run_dir: str | Path | None, resume: str | Path | None, overwrite: bool = False,
                    trust_pickle: bool = False) -> None:
    """Refuse an unusable run folder or resume source at once, before the run's first line and
    its environment check: checked only, nothing made or removed (:func:`prepare_run` claims
    the folder after the checks).

    :raises ValueError: as :func:`prepare_run`
    """
    src = resume_source(resume, trust_pickle)
    if run_dir is None or (src is not None and Path(run_dir).resolve() == src.run_folder.resolve()):
        return
    prepare_output_dir(run_dir, owned=RUN_FILES, overwrite=overwrite, option="--out", dry_run=True,
                       command=COMMAND)


def resume_source(resume: str | Path | None, trust_pickle: bool = False) -> _Resume | None:
    """The checked resume source (None without ``resume``): its files are read and checked
    here (weights, optimiser state, counters, statistics and their fingerprints), before any
    folder is touched.

    :raises ValueError: missing, refused or unreadable checkpoint (one line naming the file)
    """
    if resume is None:
        return None
    p = Path(resume)
    if not p.exists():
        raise ValueError(f"resume checkpoint not found: {p}")
    return _Resume(p, trust_pickle)


def later_checkpoints(run: Path, steps: int) -> list[Path]:
    """The checkpoint folders of ``run`` past ``steps`` (on resume: the abandoned branch)."""
    return sorted(d for d in (run / "checkpoints").glob("*_steps")
                  if _CKPT_RE.match(d.name) and steps >= 0 and int(d.name[:-6]) > steps)


def _drop_abandoned(run: Path, src: _Resume | None) -> None:
    """Remove the checkpoints past the resume point -- only once the resumed model is built
    from the checkpoint (a failed resume never deletes a checkpoint).
    """
    import shutil

    if src is None or src.foreign or src.run_folder.resolve() != run.resolve():
        return
    for d in later_checkpoints(run, src.steps):
        shutil.rmtree(d)


def train(config: TrainConfig | Mapping[str, Any] | str | Path, run_dir: str | Path | None = None,
          resume: str | Path | None = None, overwrite: bool = False,
          trust_pickle: bool = False, progress: bool | None = None) -> Path:
    """Train the configured algorithm (CPU) and write the run folder (see the module doc).

    :param config: a :class:`TrainConfig`, a mapping of its keys, a YAML path or a shipped name
    :param run_dir: output folder, default None: ``runs/<algo>-<timestamp>/`` for a new run,
        the checkpoint's run folder on resume
    :param resume: a checkpoint folder (``<run>/checkpoints/<N>_steps``, or a finished run
        folder) to continue from; a foreign SB3 ``.zip`` only with ``trust_pickle``
    :param overwrite: a new run may replace the run files in ``run_dir``
    :param trust_pickle: allow a foreign (pickled) resume source
    :param progress: show the run's steps on stderr, a bar with its ETA on a terminal, a line
        every tenth of the run otherwise (None: the config's ``progress_bar``); a run-time
        choice, not written into the run's config
    :return: the run folder
    :raises ValueError: bad config (or a sweep: ``dss14 train --train-seeds``), unusable folder,
        unmakeable environment, missing or refused checkpoint, budget already reached, or an
        architecture that differs from the checkpoint's
    :raises TrainingInterrupted: on Ctrl-C (SIGINT) or SIGTERM: the run stops at the next
        environment step and saves a checkpoint there (a second signal stops at once, keeping
        the last periodic checkpoint); a KeyboardInterrupt naming the checkpoint and the
        command that resumes from it
    """
    cfg = as_config(config)
    if cfg.sweep:
        raise ValueError(f"{cfg.source}: field 'sweep': a sweep trains one campaign per point "
                         f"(dss14 train --train-seeds ... --out DIR, or dss14_env.agents.sweep.train_sweep)")
    # everything checked before the folder is claimed (nothing removed before that)
    src = resume_source(resume, trust_pickle)
    plan, obs_space, act_space, env_config = check_env(cfg)
    if plan.dss14:
        check_seed_protocol(cfg.seed, cfg.n_envs, cfg.eval_seeds, cfg.source)
        warm = max(t.warmup_steps for t in validation_tasks(cfg, plan))
        if cfg.eval_freq and cfg.eval_episode_steps <= warm + 1:
            raise ValueError(f"{cfg.source}: key 'eval_episode_steps': the validation episodes "
                             f"must be longer than the {warm}-step warm-up the 3-sigma leaves "
                             f"out, got {cfg.eval_episode_steps}")
    if src is not None and not src.foreign:
        if src.steps >= cfg.total_timesteps:
            raise ValueError(f"checkpoint {src.path} is at {src.steps} steps, total_timesteps is "
                             f"{cfg.total_timesteps}: raise total_timesteps (--timesteps)")
        src.check_spaces(obs_space, act_space)
    run, src = prepare_run(cfg, run_dir, src, overwrite, trust_pickle)
    with manifest_kept(run):
        return _train_in(cfg, run, src, plan, obs_space, act_space, env_config,
                         cfg.progress_bar if progress is None else bool(progress))


def _train_in(cfg: TrainConfig, run: Path, src: _Resume | None, plan: EnvPlan, obs_space: Any,
              act_space: Any, env_config: Any, progress: bool) -> Path:
    """The training itself, in the claimed run folder (see :func:`train`)."""
    import stable_baselines3
    import torch
    from stable_baselines3.common.vec_env import VecNormalize
    from threadpoolctl import threadpool_limits

    say = print if cfg.verbose else (lambda *a, **k: None)
    run_id = src.run_id if src is not None else new_run_id()
    config_text = _config_text(cfg, run_id)
    tb = None
    if _installed("tensorboard"):
        tb = str(run / "tb")
    else:
        print("note: tensorboard is not installed; training curves go to monitor/ and "
              "eval/evaluations.npz only (pip install tensorboard)")

    torch.set_num_threads(cfg.torch_threads)
    monitor = run / "monitor" / (f"resume_{max(src.steps, 0)}_steps" if src is not None else "")
    record_files(monitor_files(cfg, plan, monitor))  # listed in the manifest before they exist
    venv = make_train_vec_env(cfg, plan, env_config, monitor)
    venv = VecNormalize(venv, norm_obs=cfg.normalize_obs, norm_reward=cfg.normalize_reward,
                        gamma=cfg.gamma)
    cls = algo_class(cfg.algo)
    policy_name = "MlpLstmPolicy" if is_recurrent(cfg.algo) else "MlpPolicy"
    ckpts: list[Path] = []
    model = None
    requests = StopRequests()  # a stop asked for from here on ends the training at its next step
    try:
        with requests:
            model = cls(policy_name, venv, policy_kwargs=policy_kwargs(cfg), seed=cfg.seed,
                        device="cpu", tensorboard_log=tb, verbose=cfg.verbose, **algo_kwargs(cfg))
            start = 0
            if src is not None:
                start = _restore(model, venv, src, cfg)
                if start >= cfg.total_timesteps:
                    raise ValueError(f"checkpoint {src.path} is at {start} steps, total_timesteps is "
                                     f"{cfg.total_timesteps}: raise total_timesteps (--timesteps)")
                model.num_timesteps = start
                _drop_abandoned(run, src)
                say(f"resuming {src.path} at {start} steps")
            atomic_write_text(run / CONFIG, config_text)
            update_manifest(run)
            callbacks = _callbacks(cfg, plan, run, run_id, config_text, venv, start, ckpts, requests)
            say(f"{cfg.algo} on {cfg.env_id}: {cfg.n_envs} envs ({vec_env_kind(cfg, plan)}), "
                f"obs {obs_space.shape}, action {act_space.shape}, {cfg.total_timesteps - start} "
                f"steps -> {run}")
            t0 = time.perf_counter()
            shown = progress_callback(cfg.total_timesteps, start, run.name, enabled=progress)
            watch = [stop_callback(requests, shown.write), shown]
            try:
                with threadpool_limits(limits=1):
                    model.learn(total_timesteps=cfg.total_timesteps - start, callback=watch + callbacks,
                                tb_log_name=cfg.algo, reset_num_timesteps=src is None)
            except KeyboardInterrupt as exc:  # a second signal: stopped at once, no new checkpoint
                last = ckpts[-1] if ckpts else last_checkpoint(run)
                raise TrainingInterrupted(run, int(model.num_timesteps), last,
                                          _resume_command(cfg, run, last),
                                          getattr(exc, "signum", signal.SIGINT)) from None
            except WORKERS_GONE:
                if requests.signum is None:
                    raise
                # the stop reached subprocess workers too (a SIGTERM to the process group): they
                # are gone, the model and its statistics are here, and the run stops as asked
            if requests.signum is not None and model.num_timesteps < cfg.total_timesteps:
                kept = _stop_checkpoint(cfg, run, run_id, model, venv, config_text)
                raise TrainingInterrupted(run, int(model.num_timesteps), kept,
                                          _resume_command(cfg, run, kept), requests.signum)
            wall = time.perf_counter() - t0
            save_checkpoint(run, cfg, run_id, model, venv, config_text)
    finally:
        try:
            venv.close()
        except WORKERS_GONE:  # workers stopped by the signal that stops the run
            if requests.signum is None:
                raise
    summary = {
        "algo": cfg.algo, "env_id": cfg.env_id, "run_id": run_id,
        "num_timesteps": int(model.num_timesteps), "start_timesteps": start,
        "wall_s": round(wall, 3), "steps_per_s": round((model.num_timesteps - start) / wall, 1),
        "resumed_from": None if src is None else str(src.path), "seed": cfg.seed,
        "n_envs": cfg.n_envs, "vec_env": vec_env_kind(cfg, plan),
        "torch_threads": cfg.torch_threads,
        "versions": {"stable_baselines3": stable_baselines3.__version__,
                     "torch": torch.__version__, "numpy": np.__version__},
    }
    atomic_write_text(run / "train_summary.json", json.dumps(summary, indent=2) + "\n")
    say(f"{model.num_timesteps} steps in {wall:.1f} s ({summary['steps_per_s']} steps/s); "
        f"run folder {run}")
    if requests.signum is not None:  # asked to stop as the run ended: the run is whole, and the
        raise Stopped(requests.signum)  # stop goes on to the caller (a campaign stops), whatever
    return run                          # handler the signal has there


def last_checkpoint(run: Path, before: int | None = None) -> Path | None:
    """The latest complete checkpoint folder of a run (None: none written yet), or the latest
    of fewer than ``before`` steps.
    """
    found = [(int(d.name[:-6]), d) for d in (run / "checkpoints").glob("*_steps")
             if _CKPT_RE.match(d.name) and (d / COUNTERS).is_file()
             and (before is None or int(d.name[:-6]) < before)]
    return max(found)[1] if found else None


def config_for_command(algo: str, config: str | Path | None = None, env_id: str | None = None,
                       resume: str | Path | None = None, timesteps: int | None = None,
                       seed: int | None = None, env_module: str | None = None) -> TrainConfig:
    """The configuration ``dss14 train <algo>`` runs with.

    ``--config`` (a path or a shipped name) wins; else ``--env`` takes the entry of the
    shipped hyperparameter file of ``algo``; else, with ``--resume``, the checkpoint's
    ``config.yaml``; else the shipped ``configs/<algo>.yaml``.  ``--timesteps`` and ``--seed``
    override.  ``--env-module`` (``env_module``) is the user's opt-in to import a module of
    theirs that registers ``env_id``: it is imported here, and the file may name it.

    :raises ValueError: both ``--config`` and ``--env``, or a config of another algorithm
    """
    from dss14_env.agents.config import shipped_config_path
    from dss14_env.agents.hyperparams import load_hyperparams

    if config is not None and env_id is not None:
        raise ValueError("give --config or --env, not both (--env picks the shipped "
                         "hyperparameters of that environment id)")
    if env_module is not None:
        import_user_module(env_module)
    if config is not None:
        cfg = load_config(config, env_module)
    elif env_id is not None:
        cfg = load_hyperparams(algo, env_id)
    elif resume is not None and resume_config_path(resume) is not None:
        cfg = load_config(resume_config_path(resume), env_module)
    else:
        cfg = load_config(shipped_config_path(f"{algo}.yaml"))
    if cfg.algo != algo:
        raise ValueError(f"{cfg.source}: key 'algo': the config is for {cfg.algo!r}, the command "
                         f"trains {algo!r}")
    changes = {k: v for k, v in (("total_timesteps", timesteps), ("seed", seed),
                                 ("env_module", env_module)) if v is not None}
    if changes:
        cfg = cfg.replace(source=f"{cfg.source} (command line)", **changes)
    return cfg


def import_user_module(name: str) -> None:
    """Import the module the user named with ``--env-module`` (their explicit opt-in).

    :raises ValueError: not a module name, or the module cannot be imported (one line)
    """
    import importlib

    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*", name):
        raise ValueError(f"--env-module: must be a module name (package.module), got {name!r}")
    try:
        importlib.import_module(name)
    except ImportError as exc:
        raise ValueError(f"--env-module {name}: cannot be imported ({exc})") from None


def load_run_config(run: str | Path) -> TrainConfig:
    """The configuration of a run folder (or policy folder)."""
    return load_config(Path(run) / CONFIG)


__all__ = ["RUN_FILES", "TrainingInterrupted", "config_for_command", "import_user_module", "read_counters",
           "last_checkpoint", "later_checkpoints", "load_run_config", "prepare_run", "resume_source",
           "resume_config_path", "save_checkpoint", "selection_key", "selection_score", "train",
           "validation_tasks"]
