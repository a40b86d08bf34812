"""Policy folders and checkpoints on disk, read back without unpickling anything.

A **policy folder** holds one trained policy::

    policy.pt            network weights: a dict of tensors and plain values, written with
                         torch.save, read with torch.load(weights_only=True)
    normalization.npz    observation statistics (mean, var, count, clip, epsilon; with the
                         return statistics for resuming), read with allow_pickle=False;
                         absent when the run did not normalise observations
    config.yaml          the run's resolved configuration (yaml.safe_load): the architecture
                         is rebuilt from it

A run folder is a policy folder (its final policy), so are its ``eval/best/`` and every
``checkpoints/<N>_steps/`` folder; a checkpoint adds ``optimizer.pt`` (the optimisers'
state dicts, ``weights_only=True``), ``counters.json`` and, for SAC, ``replay_buffer.npz``.
:func:`find_policy_files` never looks outside the folder it is given.

``policy.pt`` and ``normalization.npz`` both carry a **fingerprint** (format, algorithm, run
id, observation and action sizes); loading checks that the two belong to the same run and
that the weights fit the architecture of ``config.yaml``, so a model paired with another
run's statistics is refused at load time with one line naming the files.

A foreign stable-baselines3 policy (``model.zip`` + ``vecnormalize.pkl``) stores pickled
Python objects, and unpickling runs whatever code the file names: it is read only with the
explicit opt-in ``trust_pickle=True`` (CLI ``--trust-pickle``), and :func:`convert_sb3_policy`
turns it into a policy folder once.
"""

from __future__ import annotations

import json
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.core.arrays import ArrayFileError, read_arrays
from dss14_env.core.outdir import atomic_write_bytes, atomic_write_text

#: the format tag of policy.pt / normalization.npz
FORMAT = "dss14-policy-1"
WEIGHTS = "policy.pt"
STATS = "normalization.npz"
CONFIG = "config.yaml"
OPTIMIZER = "optimizer.pt"
COUNTERS = "counters.json"
REPLAY = "replay_buffer.npz"
#: files a foreign SB3 policy folder has
SB3_MODEL = "model.zip"
SB3_STATS = "vecnormalize.pkl"
#: the arrays of a SAC replay buffer file
REPLAY_FIELDS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")
#: most elements of a normalization.npz (all its arrays together: two vectors of one per
#: observation entry, a few scalars and the fingerprint's characters)
MAX_STATS_ELEMENTS = 1 << 20
TRUST_HINT = "pass trust_pickle=True (CLI --trust-pickle) only for a file you trust"


class PolicyFileError(ValueError):
    """A policy folder or file that cannot be used; one line naming the file."""


def new_run_id() -> str:
    """A fresh run id (random, 12 hex digits)."""
    return uuid.uuid4().hex[:12]


# ------------------------------------------------------------------------------ layout
@dataclass(frozen=True)
class PolicyFiles:
    """The files of one policy.

    :param folder: the policy folder
    :param weights: ``policy.pt`` (None for a foreign SB3 policy)
    :param stats: ``normalization.npz`` or None
    :param config: ``config.yaml`` (None only for a foreign SB3 policy without one)
    :param sb3_zip: a foreign SB3 ``.zip`` (needs ``trust_pickle``), else None
    :param sb3_stats: its ``vecnormalize.pkl`` or None
    """

    folder: Path
    weights: Path | None
    stats: Path | None
    config: Path | None
    sb3_zip: Path | None = None
    sb3_stats: Path | None = None

    @property
    def foreign(self) -> bool:
        """A pickled stable-baselines3 policy (loads only with ``trust_pickle``)."""
        return self.sb3_zip is not None


def _sb3_stats_for(model: Path) -> Path | None:
    """``vecnormalize.pkl`` beside ``model.zip``; ``ppo_vecnormalize_<N>_steps.pkl`` beside
    an SB3 checkpoint ``ppo_<N>_steps.zip``.
    """
    name = model.name
    if name.endswith("_steps.zip") and "_" in name:
        prefix, steps = name[:-len("_steps.zip")].rsplit("_", 1)
        cand = model.with_name(f"{prefix}_vecnormalize_{steps}_steps.pkl")
        if cand.is_file():
            return cand
    cand = model.with_name(SB3_STATS)
    return cand if cand.is_file() else None


def find_policy_files(path: str | Path) -> PolicyFiles:
    """The files of the policy at ``path`` (a policy folder, or a foreign SB3 ``.zip``).

    Nothing is read or unpickled here; only the folder itself is searched.

    :param path: a policy folder (run folder, ``eval/best``, ``checkpoints/<N>_steps``), a
        ``policy.pt`` inside one, or a stable-baselines3 ``.zip`` (foreign)
    :raises PolicyFileError: one line naming the path and what is missing
    """
    p = Path(path)
    if p.is_file() and p.name == WEIGHTS:
        p = p.parent
    if p.is_dir():
        w = p / WEIGHTS
        if w.is_file():
            cfg = p / CONFIG
            if not cfg.is_file():
                raise PolicyFileError(f"policy folder {p}: {CONFIG} is missing (a policy folder "
                                      f"holds {WEIGHTS}, {CONFIG} and {STATS} if normalised)")
            s = p / STATS
            return PolicyFiles(p, w, s if s.is_file() else None, cfg)
        if (p / SB3_MODEL).is_file():
            z = p / SB3_MODEL
            cfg = p / CONFIG
            return PolicyFiles(p, None, None, cfg if cfg.is_file() else None, z, _sb3_stats_for(z))
        raise PolicyFileError(f"no policy at {p}: expected a folder with {WEIGHTS} and {CONFIG}")
    if p.suffix == ".zip" or p.with_suffix(".zip").is_file():
        z = p if p.suffix == ".zip" else p.with_suffix(".zip")
        if not z.is_file():
            raise PolicyFileError(f"no policy at {p}: file not found")
        folder = z.parent.parent if z.parent.name == "checkpoints" else z.parent
        cfg = folder / CONFIG
        return PolicyFiles(z.parent, None, None, cfg if cfg.is_file() else None, z,
                           _sb3_stats_for(z))
    raise PolicyFileError(f"no policy at {p}: expected a folder with {WEIGHTS} and {CONFIG}")


def policy_problem(path: str | Path | None, trust_pickle: bool = False) -> str | None:
    """Why the policy at ``path`` cannot be loaded (one line), or None.

    Checks the layout and, without ``trust_pickle``, refuses a foreign pickled policy; the
    files' contents are checked when the policy is loaded.
    """
    if path is None:
        return "no policy path given"
    try:
        files = find_policy_files(path)
    except PolicyFileError as exc:
        return str(exc)
    if files.foreign and not trust_pickle:
        return refuse_pickle_message(files.sb3_zip)
    return None


def refuse_pickle_message(path: Path | None) -> str:
    """The one-line refusal of a pickled file without the opt-in."""
    return (f"{path}: a stable-baselines3 file stores pickled Python objects, which can run "
            f"code when loaded; {TRUST_HINT}, or convert it once with "
            f"dss14_env.agents.storage.convert_sb3_policy")


# ------------------------------------------------------------------------------ weights
def _torch_save(obj: Any, path: Path) -> None:
    import io

    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write_bytes(path, buf.getvalue())


def _torch_load(path: Path, what: str) -> Any:
    import pickle

    import torch

    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise PolicyFileError(f"{path}: {what} file not found") from None
    except (pickle.UnpicklingError, RuntimeError, EOFError, ValueError, zipfile.BadZipFile,
            OSError, AttributeError, TypeError, KeyError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if "weights_only" in str(exc) or "Unsupported global" in str(exc):
            first = "it holds Python objects other than tensors and plain values (refused)"
        raise PolicyFileError(f"{path}: not a readable {what} file ({first[:160]})") from None


def _plain_tensors(state: dict) -> dict:
    return {k: v.detach().cpu().clone() for k, v in state.items()}


def save_weights(path: Path, state_dict: dict, fingerprint: dict[str, Any]) -> None:
    """Write ``policy.pt``: the fingerprint and the policy's state dict."""
    _torch_save({**fingerprint, "format": FORMAT, "state_dict": _plain_tensors(state_dict)}, path)


def load_weights(path: Path) -> tuple[dict[str, Any], dict]:
    """``(fingerprint, state_dict)`` of a ``policy.pt`` (``torch.load(weights_only=True)``).

    :raises PolicyFileError: unreadable, refused (pickled objects) or not this format
    """
    data = _torch_load(path, "policy weights")
    if not isinstance(data, dict) or data.get("format") != FORMAT or \
            not isinstance(data.get("state_dict"), dict):
        raise PolicyFileError(f"{path}: not a policy weights file of format {FORMAT}")
    fp = {k: v for k, v in data.items() if k != "state_dict"}
    for key in ("algo", "run_id", "obs_dim", "act_dim"):
        if key not in fp:
            raise PolicyFileError(f"{path}: fingerprint field {key!r} is missing")
    for name, value in data["state_dict"].items():
        if hasattr(value, "is_floating_point") and value.is_floating_point() and \
                not bool(value.isfinite().all()):
            raise PolicyFileError(f"{path}: weight {name!r} holds NaN or infinite values; a policy "
                                  f"with such weights acts NaN and scores nothing")
    return fp, data["state_dict"]


# ------------------------------------------------------------------------------ statistics
@dataclass
class NormStats:
    """Observation (and return) normalisation statistics of a run (VecNormalize's)."""

    obs_mean: np.ndarray
    obs_var: np.ndarray
    obs_count: float
    clip_obs: float
    epsilon: float
    ret_mean: np.ndarray | None = None
    ret_var: np.ndarray | None = None
    ret_count: float | None = None
    clip_reward: float | None = None

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """VecNormalize.normalize_obs with these (frozen) statistics, float32."""
        return np.clip((obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon),
                       -self.clip_obs, self.clip_obs).astype(np.float32)

    @classmethod
    def from_vec_normalize(cls, vn: Any) -> NormStats:
        """The statistics of an SB3 ``VecNormalize``."""
        rr = vn.ret_rms
        return cls(np.array(vn.obs_rms.mean, np.float64), np.array(vn.obs_rms.var, np.float64),
                   float(vn.obs_rms.count), float(vn.clip_obs), float(vn.epsilon),
                   np.array(rr.mean, np.float64), np.array(rr.var, np.float64), float(rr.count),
                   float(vn.clip_reward))

    def apply_to(self, vn: Any) -> None:
        """Set an SB3 ``VecNormalize``'s statistics (for resuming)."""
        vn.obs_rms.mean, vn.obs_rms.var = self.obs_mean.copy(), self.obs_var.copy()
        vn.obs_rms.count = self.obs_count
        if self.ret_mean is not None:
            vn.ret_rms.mean, vn.ret_rms.var = self.ret_mean.copy(), self.ret_var.copy()
            vn.ret_rms.count = self.ret_count


def save_stats(path: Path, stats: NormStats, fingerprint: dict[str, Any]) -> None:
    """Write ``normalization.npz`` (no object arrays)."""
    import io

    arrays = {"obs_mean": stats.obs_mean, "obs_var": stats.obs_var,
              "obs_count": np.float64(stats.obs_count), "clip_obs": np.float64(stats.clip_obs),
              "epsilon": np.float64(stats.epsilon),
              "fingerprint": np.array(json.dumps({**fingerprint, "format": FORMAT},
                                                 sort_keys=True))}
    if stats.ret_mean is not None:
        arrays.update(ret_mean=stats.ret_mean, ret_var=stats.ret_var,
                      ret_count=np.float64(stats.ret_count),
                      clip_reward=np.float64(stats.clip_reward))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_stats(path: Path) -> tuple[dict[str, Any], NormStats]:
    """``(fingerprint, stats)`` of a ``normalization.npz`` (``allow_pickle=False``).

    :raises PolicyFileError: unreadable, object arrays, missing fields, non-finite values
    """
    try:
        a = read_arrays(path, MAX_STATS_ELEMENTS, MAX_STATS_ELEMENTS * 8)
    except ArrayFileError as exc:
        if not Path(path).is_file():
            raise PolicyFileError(f"{path}: normalisation statistics file not found") from None
        raise PolicyFileError(str(exc).replace(": not a readable array file", ": not a readable "
                                               "normalisation statistics file")) from None
    for key in ("obs_mean", "obs_var", "obs_count", "clip_obs", "epsilon", "fingerprint"):
        if key not in a:
            raise PolicyFileError(f"{path}: field {key!r} is missing")
    try:
        fp = json.loads(str(a["fingerprint"]))
    except json.JSONDecodeError:
        raise PolicyFileError(f"{path}: field 'fingerprint' is not valid JSON") from None
    if not isinstance(fp, dict) or fp.get("format") != FORMAT:
        raise PolicyFileError(f"{path}: not a normalisation file of format {FORMAT}")
    mean, var = _real(a, "obs_mean", path), _real(a, "obs_var", path)
    if mean.ndim != 1 or mean.shape != var.shape or not np.all(var >= 0):
        raise PolicyFileError(f"{path}: field 'obs_mean'/'obs_var' must be finite vectors of one "
                              f"size (var >= 0)")
    ret = {}
    if "ret_mean" in a:
        ret = dict(ret_mean=_real(a, "ret_mean", path), ret_var=_real(a, "ret_var", path),
                   ret_count=_scalar(a, "ret_count", path), clip_reward=_scalar(a, "clip_reward", path))
    return fp, NormStats(mean, var, _scalar(a, "obs_count", path, positive=False),
                         _scalar(a, "clip_obs", path), _scalar(a, "epsilon", path), **ret)


def _real(a: dict[str, np.ndarray], key: str, path: Path) -> np.ndarray:
    """Field ``key`` of a statistics file as float64: present, of real numbers (a complex field
    is refused, not cast), every value finite.
    """
    v = np.asarray(a.get(key))
    if v.dtype.kind not in "fiu" or not np.isfinite(v).all():
        raise PolicyFileError(f"{path}: field {key!r} must hold finite real numbers")
    return v.astype(np.float64)


def _scalar(a: dict[str, np.ndarray], key: str, path: Path, positive: bool = True) -> float:
    """The number of field ``key`` of a statistics file: one finite value, > 0 (or >= 0): a
    NaN clip or a negative epsilon would make every normalised observation NaN.
    """
    v = np.asarray(a.get(key))
    ok = v.size == 1 and v.dtype.kind in "fiu" and np.isfinite(v).all()
    if not ok or (float(v.flat[0]) <= 0 if positive else float(v.flat[0]) < 0):
        raise PolicyFileError(f"{path}: field {key!r} must be one finite number "
                              f"{'> 0' if positive else '>= 0'}, got {v.ravel()[:3].tolist()}")
    return float(v.flat[0])


def check_fingerprints(weights: Path, wfp: dict, stats: Path, sfp: dict) -> None:
    """Refuse weights and statistics of different runs or sizes (one line naming both)."""
    for key in ("run_id", "obs_dim"):
        if wfp.get(key) != sfp.get(key):
            raise PolicyFileError(f"{stats}: belongs to another run than {weights} ({key} "
                                  f"{sfp.get(key)!r} vs {wfp.get(key)!r}); a policy folder "
                                  f"must hold the weights and statistics of one run")


# ------------------------------------------------------------------------------ folders
def write_policy_folder(folder: Path, policy: Any, stats: NormStats | None,
                        fingerprint: dict[str, Any], config_text: str) -> None:
    """Write a policy folder (weights, statistics, config) atomically file by file."""
    folder.mkdir(parents=True, exist_ok=True)
    save_weights(folder / WEIGHTS, policy.state_dict(), fingerprint)
    if stats is not None:
        save_stats(folder / STATS, stats, fingerprint)
    elif (folder / STATS).exists():
        (folder / STATS).unlink()
    atomic_write_text(folder / CONFIG, config_text)


def save_optimizers(path: Path, model: Any) -> None:
    """Write ``optimizer.pt``: every optimiser's state dict (and SAC's entropy coefficient)."""
    params = model.get_parameters()
    opt = {k: v for k, v in params.items() if k != "policy"}
    extra = {}
    if getattr(model, "log_ent_coef", None) is not None:
        extra["log_ent_coef"] = model.log_ent_coef.detach().cpu().clone()
    _torch_save({"format": FORMAT, "optimizers": opt, "tensors": extra}, path)


def load_optimizers(path: Path) -> tuple[dict, dict]:
    """``(optimizer state dicts, tensors)`` of ``optimizer.pt`` (``weights_only=True``)."""
    data = _torch_load(path, "optimizer state")
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise PolicyFileError(f"{path}: not an optimizer state file of format {FORMAT}")
    return data["optimizers"], data.get("tensors", {})


def save_replay_buffer(path: Path, buffer: Any) -> None:
    """Write SAC's replay buffer (the filled part) as npz."""
    import io

    n = buffer.buffer_size if buffer.full else buffer.pos
    arrays = {k: getattr(buffer, k)[:n] for k in REPLAY_FIELDS if getattr(buffer, k, None) is not None}
    buf = io.BytesIO()
    np.savez(buf, pos=np.int64(buffer.pos), full=np.bool_(buffer.full), **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_replay_buffer(path: Path, buffer: Any) -> None:
    """Fill SAC's replay buffer from :func:`save_replay_buffer`'s file (refused before reading
    when its headers claim more than the buffer holds).
    """
    fields = [getattr(buffer, k) for k in REPLAY_FIELDS if getattr(buffer, k, None) is not None]
    cap = sum(int(f.size) for f in fields) + 2
    try:
        d = read_arrays(path, cap, sum(int(f.nbytes) for f in fields) + 16)
        n = d["observations"].shape[0]
        if n > buffer.buffer_size:
            raise PolicyFileError(f"{path}: {n} transitions do not fit buffer_size "
                                  f"{buffer.buffer_size}")
        for k in REPLAY_FIELDS:
            if k in d and getattr(buffer, k, None) is not None:
                getattr(buffer, k)[:n] = d[k]
        buffer.pos, buffer.full = int(d["pos"]) % buffer.buffer_size, bool(d["full"])
    except (ValueError, OSError, zipfile.BadZipFile, KeyError) as exc:
        if isinstance(exc, (PolicyFileError, ArrayFileError)):
            raise PolicyFileError(str(exc)) from None
        raise PolicyFileError(f"{path}: not a readable replay buffer file ({exc})") from None


# ------------------------------------------------------------------------------ foreign SB3
def load_sb3_model(files: PolicyFiles, algo_class: Any, trust_pickle: bool) -> tuple[Any, Any]:
    """``(model, VecNormalize or None)`` of a foreign SB3 policy -- unpickles; opt-in only.

    :raises PolicyFileError: without ``trust_pickle`` (one line naming the file and the opt-in)
    """
    if not trust_pickle:
        raise PolicyFileError(refuse_pickle_message(files.sb3_zip))
    import pickle

    try:
        model = algo_class.load(files.sb3_zip, device="cpu")
    except (AssertionError, ValueError, KeyError, zipfile.BadZipFile, RuntimeError,
            pickle.UnpicklingError, EOFError) as exc:
        raise PolicyFileError(f"{files.sb3_zip}: not a readable stable-baselines3 model "
                              f"({type(exc).__name__}: {str(exc)[:120]})") from None
    vn = None
    if files.sb3_stats is not None:
        try:
            with open(files.sb3_stats, "rb") as fh:
                vn = pickle.load(fh)  # noqa: S301 - opt-in (trust_pickle) only
        except (pickle.UnpicklingError, EOFError, AttributeError, ValueError) as exc:
            raise PolicyFileError(f"{files.sb3_stats}: not a readable VecNormalize pickle "
                                  f"({type(exc).__name__})") from None
    return model, vn


def convert_sb3_policy(src: str | Path, dst: str | Path, trust_pickle: bool = False,
                       algo: str = "ppo", run_id: str | None = None) -> Path:
    """Turn a foreign SB3 policy (``model.zip`` + ``vecnormalize.pkl``, and its run's
    ``config.yaml``) into a policy folder -- the one time its pickles are read.

    :param src: SB3 run folder or ``.zip``
    :param dst: the new policy folder
    :param trust_pickle: must be True: the source is unpickled
    :param algo: ``ppo``, ``recurrent_ppo`` or ``sac``
    :param run_id: fingerprint run id, default a fresh one
    :return: ``dst``
    """
    from dss14_env.agents.algos import algo_class

    files = find_policy_files(src)
    if not files.foreign:
        raise PolicyFileError(f"{src}: already a policy folder")
    if files.config is None:
        raise PolicyFileError(f"{src}: no {CONFIG} beside the model (the architecture and "
                              f"environment are rebuilt from it)")
    model, vn = load_sb3_model(files, algo_class(algo), trust_pickle)
    fp = {"algo": algo, "run_id": run_id or new_run_id(),
          "obs_dim": int(np.prod(model.observation_space.shape)),
          "act_dim": int(np.prod(model.action_space.shape)),
          "num_timesteps": int(model.num_timesteps)}
    stats = None if vn is None or not vn.norm_obs else NormStats.from_vec_normalize(vn)
    write_policy_folder(Path(dst), model.policy, stats, fp, files.config.read_text())
    return Path(dst)


__all__ = ["CONFIG", "COUNTERS", "FORMAT", "NormStats", "OPTIMIZER", "PolicyFileError",
           "PolicyFiles", "REPLAY", "STATS", "WEIGHTS", "check_fingerprints",
           "convert_sb3_policy", "find_policy_files", "load_optimizers", "load_replay_buffer",
           "load_sb3_model", "load_stats", "load_weights", "new_run_id", "policy_problem",
           "refuse_pickle_message", "save_optimizers", "save_replay_buffer", "save_stats",
           "save_weights", "write_policy_folder"]
