"""dss14-env: calibrated model and Gymnasium environment of the DSS-14 antenna servo.

The model follows W. Gawronski and R. Bartos, "Modeling and Analysis of the DSS-14 Antenna
Control System", JPL TDA Progress Report 42-124 (1996), called [R] in the docstrings.

Importing the package registers the Gymnasium environments ``DSS14-v0`` (track in random
gusty wind), ``DSS14-Hold-v0``, ``DSS14-Step-v0`` and ``DSS14-Slew-v0`` (docs/env.md); nothing
is built at import.
"""

__version__ = "0.1.0"


def _register_envs() -> None:
    """Register the Gymnasium environments (docs/env.md); cheap: nothing is built here."""
    from gymnasium.envs.registration import register, registry

    eight = [45.0 * i for i in range(8)]  # wind directions, deg (0 = front)
    variants = {
        # id: (max_episode_steps, kwargs): 60 s / 40 s at the default 50 Hz; the other settings
        # come from configs/env.yaml
        "DSS14-v0": (3000, {"scenario": "track", "wind_speed_kmh": "random",
                            "wind_speed_grid_kmh": [30.0, 40.0, 50.0, 60.0, 70.0],
                            "wind_direction": "random", "wind_direction_grid_deg": eight}),
        "DSS14-Hold-v0": (3000, {"scenario": "hold", "wind_speed_kmh": 50.0, "wind_direction": "random",
                                 "wind_direction_grid_deg": [0.0, 90.0]}),
        "DSS14-Step-v0": (2000, {"scenario": "step", "step_deg": 0.1, "step_axes": "both", "wind_speed_kmh": 0.0}),
        "DSS14-Slew-v0": (3000, {"scenario": "slew", "slew_deg": 5.0, "wind_speed_kmh": 30.0,
                                 "wind_direction": "random", "wind_direction_grid_deg": eight}),
    }
    for env_id, (steps, kwargs) in variants.items():
        if env_id not in registry:
            register(id=env_id, entry_point="dss14_env.env:DSS14Env",
                     vector_entry_point="dss14_env.vector_env:DSS14VectorEnv",
                     max_episode_steps=steps, kwargs=kwargs)


_register_envs()
