"""Learned controllers: training (stable-baselines3 PPO, RecurrentPPO, SAC), trained policies
behind the controller interface, residual and model-informed policy interfaces.

Importing this package registers the agents' environment ids (nothing is built):
``DSS14-Plain-v0``, ``DSS14-Residual-v0``, ``DSS14-ResidualLQG-v0``, ``DSS14-KalmanObs-v0``
(:mod:`dss14_env.agents.envs`).

Installed as ``dss14_env.agents``.  May import: ``baselines``, ``envs``, ``wind``, ``model``,
``core`` (``docs/architecture.md``).
"""

#: the agents' registered ids and their entry points
AGENT_ENV_IDS = {
    "DSS14-Plain-v0": "dss14_env.agents.envs:make_plain_env",
    "DSS14-Residual-v0": "dss14_env.agents.residual:make_residual_env",
    "DSS14-ResidualLQG-v0": "dss14_env.agents.envs:make_residual_lqg_env",
    "DSS14-KalmanObs-v0": "dss14_env.agents.envs:make_kalman_obs_env",
}


def register_agent_envs() -> None:
    """Register :data:`AGENT_ENV_IDS` with Gymnasium (idempotent; builds nothing).

    The base environment's ``TimeLimit`` truncates, so the ids have no episode limit of their own;
    like the base ids, they are registered without gymnasium's passive checker
    (:data:`dss14_env.envs.presets.DISABLE_ENV_CHECKER`).
    """
    from gymnasium.envs.registration import register, registry

    from dss14_env.envs.presets import DISABLE_ENV_CHECKER

    for env_id, entry_point in AGENT_ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, disable_env_checker=DISABLE_ENV_CHECKER)


register_agent_envs()
