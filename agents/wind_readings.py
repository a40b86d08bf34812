"""Each sub-environment's mean wind speed reading in a batched training VecEnv, for a policy
interface whose base is scheduled on it (``lqg_pointing_sched``).

The SB3 VecEnv API hands a wrapper no reset info, and an autoreset (gymnasium's SAME_STEP) starts
a sub-environment's next episode inside ``step``.  :class:`WindReadingVectorEnv` keeps every
row's reading, the reset info's ``wind_speed_mps`` (the episode's mean wind, as an anemometer
measures it; never the gust state), from each reset and autoreset in ``wind_readings_mps``;
:func:`wind_source` reads the rows of a VecEnv of them, the
:attr:`~dss14_env.agents.interface.PolicyInterface.wind_source` the interface asks at every
(auto)reset of a row.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from dss14_env.agents.vec_env import MixtureVecEnv, SameStepDSS14VectorEnv, SB3VecEnv


class WindReadingVectorEnv(SameStepDSS14VectorEnv):
    """:class:`~dss14_env.agents.vec_env.SameStepDSS14VectorEnv` that keeps each row's mean wind
    speed reading of its current episode (m/s, ``wind_readings_mps``; module doc).
    """

    #: the rows' readings (``(num_envs,)``, NaN before the first reset)
    wind_readings_mps: np.ndarray | None = None

    def _reset_rows(self, idx: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super()._reset_rows(idx)
        if self.wind_readings_mps is None:
            self.wind_readings_mps = np.full(self.num_envs, np.nan)
        self.wind_readings_mps[idx] = np.asarray(info["wind_speed_mps"], float)
        return obs, info


def make_reading_vec_env(env_id: str, n_envs: int, max_episode_steps: int | None = None,
                         **env_kwargs: Any) -> SB3VecEnv:
    """:func:`dss14_env.agents.vec_env.make_sb3_vec_env` (unseeded) over a
    :class:`WindReadingVectorEnv`.
    """
    spec = gym.spec(env_id)
    steps = max_episode_steps if max_episode_steps is not None else spec.max_episode_steps
    return SB3VecEnv(WindReadingVectorEnv(n_envs, max_episode_steps=steps, **{**spec.kwargs, **env_kwargs}))


def wind_source(venv: SB3VecEnv | MixtureVecEnv) -> Callable[[np.ndarray], np.ndarray]:
    """``rows -> readings`` (m/s) of a VecEnv over :class:`WindReadingVectorEnv` (one, or a
    mixture of them side by side), as they are when it is called.

    :raises ValueError: a VecEnv over another vector environment
    """
    parts = venv.parts if isinstance(venv, MixtureVecEnv) else [venv]
    if not all(isinstance(getattr(p, "venv", None), WindReadingVectorEnv) for p in parts):
        raise ValueError("wind_source: every part must be a VecEnv over WindReadingVectorEnv "
                         "(make_reading_vec_env)")

    def read(rows: np.ndarray) -> np.ndarray:
        return np.concatenate([p.venv.wind_readings_mps for p in parts])[np.asarray(rows, int)]

    return read


__all__ = ["WindReadingVectorEnv", "make_reading_vec_env", "wind_source"]
