"""Each sub-environment's mean wind speed reading in a batched training VecEnv, for a policy
interface whose base is scheduled on it (``lqg_pointing_sched``).

The SB3 VecEnv API hands a wrapper no reset info, and an autoreset (gymnasium's SAME_STEP) starts
a sub-environment's next episode inside ``step``.  The DSS14 vector environment keeps every row's
reading of its current episode (:attr:`~dss14_env.envs.vector.DSS14VectorEnv.wind_speeds_mps`,
the reset info's ``wind_speed_mps``); :func:`wind_source` reads it for the rows of a VecEnv, the
:attr:`~dss14_env.agents.interface.PolicyInterface.wind_source` the interface asks at every
(auto)reset of a row.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dss14_env.agents.vec_env import MixtureVecEnv, SB3VecEnv
from dss14_env.envs.vector import DSS14VectorEnv


def wind_source(venv: SB3VecEnv | MixtureVecEnv) -> Callable[[np.ndarray], np.ndarray]:
    """``rows -> readings`` (m/s) of a VecEnv over a DSS14 vector environment (one, or a
    mixture of them side by side), as they are when it is called.

    :raises ValueError: a VecEnv over another vector environment
    """
    parts = venv.parts if isinstance(venv, MixtureVecEnv) else [venv]
    if not all(isinstance(getattr(p, "venv", None), DSS14VectorEnv) for p in parts):
        raise ValueError("wind_source: every part must be a VecEnv over the DSS14 vector "
                         "environment (make_sb3_vec_env)")

    def read(rows: np.ndarray) -> np.ndarray:
        return np.concatenate([p.venv.wind_speeds_mps for p in parts])[np.asarray(rows, int)]

    return read


__all__ = ["wind_source"]
