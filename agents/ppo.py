"""PPO training: the names of the PPO-only versions, kept for scripts written against them.

Training of every algorithm lives in :mod:`dss14_env.agents.train`, its configuration in
:mod:`dss14_env.agents.config` (``PPOConfig`` is :class:`~dss14_env.agents.config.TrainConfig`
with ``algo: ppo``), the environments in :mod:`dss14_env.agents.envs`.

>>> cfg = PPOConfig.from_dict({"env_id": "Pendulum-v1", "n_envs": 2, "n_steps": 64,
...                            "batch_size": 64})
>>> cfg.algo, cfg.n_envs
('ppo', 2)
"""

from __future__ import annotations

from dss14_env.agents.config import PPOConfig, as_config, default_config_path, load_config
from dss14_env.agents.envs import DEFAULT_ENV_MODULES, import_env_module, make_env
from dss14_env.agents.train import train

__all__ = ["DEFAULT_ENV_MODULES", "PPOConfig", "as_config", "default_config_path",
           "import_env_module", "load_config", "make_env", "train"]
