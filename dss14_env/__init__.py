"""dss14-env: calibrated model and Gymnasium environment of the DSS-14 antenna servo.

The model follows W. Gawronski and R. Bartos, "Modeling and Analysis of the DSS-14 Antenna
Control System", JPL TDA Progress Report 42-124 (1996), called [R] in the docstrings.

Importing the package registers the Gymnasium environments of
:data:`dss14_env.envs.presets.PRESETS` (``DSS14-v0``: track in random gusty wind,
``DSS14-Hold-v0``, ``DSS14-HoldFront-v0``, ``DSS14-HoldSide-v0``, ``DSS14-Step-v0``,
``DSS14-Slew-v0``) and ``DSS14-Residual-v0`` (PPO residual on the report's PI,
:mod:`dss14_env.agents.residual`); nothing is built at import.

Layers, each importing only those below it: ``core`` <- ``model`` <- ``wind`` <- ``envs`` <-
``baselines`` <- ``agents`` <- ``bench`` / ``reproduce`` <- ``cli``.
"""

__version__ = "0.1.0"


def _register() -> None:
    from gymnasium.envs.registration import register, registry

    from dss14_env.envs.presets import register_presets

    register_presets()
    if "DSS14-Residual-v0" not in registry:  # the base env's TimeLimit truncates
        register(id="DSS14-Residual-v0", entry_point="dss14_env.agents.residual:make_residual_env")


_register()
