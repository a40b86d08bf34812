"""The one controller interface shared by the classical, optimal and learned controllers.

A controller sees only what the environment observes: it gets the observation vector of
``DSS14-v0`` (see :class:`dss14_env.envs.env.DSS14Env`) and returns an action in the environment's
action space ([-1, 1]^2, scaled rate commands).  The episode loop (``baselines/rollout.py``,
the bench's runner's) calls every controller the same way, one episode at a time::

    ctrl.reset(seed)                 # once per episode, before the first act()
    action = ctrl.act(observation)   # once per control period: (12,) -> (2,) float32
    ctrl.info                        # dict of the last call: e.g. {"solve_time_s": ...}

A controller with ``batchable = True`` also runs many episodes at once, one per row, e.g. the
sub-environments of :class:`dss14_env.envs.vector.DSS14VectorEnv`; row ``i`` then behaves
exactly as the same controller on episode ``i`` alone::

    ctrl.reset_batch(n, seeds)               # start n episodes
    actions = ctrl.act_batch(observations)   # (n, 12) -> (n, 2) float32 in [-1, 1]
    ctrl.info_batch                          # dict of per-row arrays of the last call
    ctrl.restart(mask)                       # rows whose sub-environment was reset (autoreset):
                                             # they start a new episode at the next act_batch

Keys of ``info`` (a controller sets those that apply):

* ``solve_time_s``: wall time of the last :meth:`Controller.act`, s;
* ``rate_command_rad_s``: the rate command before scaling and clipping, rad/s;
* ``n_fallbacks``: steps of the episode so far in which the controller could not use its own
  law and used a backup action (the MPC: the LQG action after a failed solve);
* ``fallbacks``: the same steps as a list of ``{"step": k, "status": s}``, ``k`` the step
  index in the episode (0 = the first :meth:`Controller.act` after :meth:`Controller.reset`),
  ``s`` the solver status that caused it -- the record the runner keeps per episode
  (``results.json``).

In ``info_batch`` every value is an array whose first axis is the row (``solve_time_s``: the
wall time of the whole :meth:`Controller.act_batch` call divided by the number of rows).

Controllers that need the control period, the action scale or the observation layout take the
environment (or its config) in their constructor, never the plant's true parameters.  Every
entry point refuses a wrong-shape or non-finite observation with a one-line
:class:`ValueError` naming it (:func:`check_observation`, :func:`check_observations`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np

#: length of the ``DSS14-v0`` observation
OBS_SIZE = 12
#: the lengths an observation may have: the encoders' 12, and 14 with the monopulse sensor
#: (its two entries last, :data:`dss14_env.envs.monopulse.OBS_NAMES`)
OBS_SIZES = (OBS_SIZE, OBS_SIZE + 2)


def check_observation(observation: Any) -> np.ndarray:
    """The observation of one episode as float64 ``(12,)`` (``(14,)`` with the monopulse sensor).

    :raises ValueError: naming the observation if it is not 12 (or 14) finite numbers
    """
    try:
        o = np.asarray(observation, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"observation must be {OBS_SIZE} numbers, got {type(observation).__name__}: "
                         f"{exc}") from None
    if o.ndim != 1 or o.shape[0] not in OBS_SIZES:
        raise ValueError(f"observation must have shape ({OBS_SIZE},) (or ({OBS_SIZES[1]},) with the "
                         f"monopulse sensor), got {o.shape}")
    if not np.all(np.isfinite(o)):
        raise ValueError(f"observation must be finite, got NaN or inf at entries "
                         f"{np.flatnonzero(~np.isfinite(o)).tolist()}")
    return o


def check_observations(observations: Any, n: int) -> np.ndarray:
    """A batch of observations as float64 ``(n, 12)`` (``(n, 14)`` with the monopulse sensor).

    :raises ValueError: naming the observations if the shape is not ``(n, 12)`` (or ``(n, 14)``)
        or an entry is not finite
    """
    try:
        o = np.asarray(observations, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"observations must be an ({n}, {OBS_SIZE}) array, got "
                         f"{type(observations).__name__}: {exc}") from None
    if o.ndim != 2 or o.shape[0] != n or o.shape[1] not in OBS_SIZES:
        raise ValueError(f"observations must have shape ({n}, {OBS_SIZE}) (or ({n}, {OBS_SIZES[1]}) with the "
                         f"monopulse sensor; the batch started by reset_batch), got {o.shape}")
    bad = ~np.isfinite(o)
    if bad.any():
        raise ValueError(f"observations must be finite, got NaN or inf in rows "
                         f"{np.flatnonzero(bad.any(axis=1)).tolist()}")
    return o


def check_mask(mask: Any, n: int) -> np.ndarray:
    """A row mask as bool ``(n,)``.

    :raises ValueError: naming the mask if it has another shape or is not boolean
    """
    m = np.asarray(mask)
    if m.shape != (n,) or m.dtype != np.bool_:
        raise ValueError(f"restart mask must be a boolean array of shape ({n},), got {m.dtype} {m.shape}")
    return m


def check_batch_size(n: Any, seeds: Sequence[int] | None) -> int:
    """The number of rows of :meth:`Controller.reset_batch`.

    :raises ValueError: naming ``n`` or ``seeds`` if ``n`` is not a positive integer or the seeds
        are not ``n``
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"reset_batch: n must be a positive integer, got {n!r}")
    if seeds is not None and len(seeds) != n:
        raise ValueError(f"reset_batch: seeds must have n = {n} entries, got {len(seeds)}")
    return int(n)


class Controller(ABC):
    """Base class of every controller scored by the runner.

    :param name: label used in tables and plots
    """

    #: True when :meth:`reset_batch`, :meth:`act_batch` and :meth:`restart` are implemented
    batchable: bool = False

    def __init__(self, name: str) -> None:
        self.name = name
        self.info: dict[str, Any] = {}
        self.info_batch: dict[str, np.ndarray] = {}

    def reset(self, seed: int | None = None) -> None:
        """Reset internal state (integrators, estimators, warm starts) for a new episode.

        :param seed: episode seed (for controllers with random parts), default None
        """
        self.info = {}

    @abstractmethod
    def act(self, observation: np.ndarray) -> np.ndarray:
        """Return the action (shape ``(2,)``, float32 in [-1, 1]) for one observation ``(12,)``."""

    def reset_batch(self, n: int, seeds: Sequence[int] | None = None) -> None:
        """Start ``n`` episodes, one per row of the following :meth:`act_batch` calls.

        :param n: number of rows
        :param seeds: the episodes' seeds (for controllers with random parts), default None
        :raises NotImplementedError: if the controller is not batchable
        """
        raise NotImplementedError(f"{type(self).__name__} is not batchable (batchable = False): "
                                  "run one episode per instance with reset() and act()")

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """Actions ``(n, 2)`` (float32 in [-1, 1]) for the rows' observations ``(n, 12)``;
        per-row information in :attr:`info_batch`.

        :raises NotImplementedError: if the controller is not batchable
        """
        raise NotImplementedError(f"{type(self).__name__} is not batchable (batchable = False)")

    def restart(self, mask: np.ndarray) -> None:
        """The rows ``mask`` (bool ``(n,)``) start a new episode at the next :meth:`act_batch`
        (their sub-environments were reset).

        :raises NotImplementedError: if the controller is not batchable
        """
        raise NotImplementedError(f"{type(self).__name__} is not batchable (batchable = False)")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
