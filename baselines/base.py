"""The one controller interface shared by the classical, optimal and learned controllers.

A controller sees only what the environment observes: it gets the observation vector of
``DSS14-v0`` (see :class:`dss14_env.envs.env.DSS14Env`) and returns an action in the environment's
action space ([-1, 1]^2, scaled rate commands).  The runner (``dss14_env/bench/runner.py``) calls
every controller the same way::

    ctrl.reset(seed)                 # once per episode, before the first act()
    action = ctrl.act(observation)   # once per control period
    ctrl.info                        # dict of the last call: e.g. {"solve_time_s": ...}

Controllers that need the control period, the action scale or the observation layout take the
environment (or its config) in their constructor, never the plant's true parameters.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np


class Controller(ABC):
    """Base class of every controller scored by the runner.

    :param name: label used in tables and plots
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.info: dict[str, Any] = {}

    def reset(self, seed: int | None = None) -> None:
        """Reset internal state (integrators, estimators, warm starts) for a new episode.

        :param seed: episode seed (for controllers with random parts), default None
        """
        self.info = {}

    @abstractmethod
    def act(self, observation: np.ndarray) -> np.ndarray:
        """Return the action (shape ``(2,)``, in [-1, 1]) for one observation."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
