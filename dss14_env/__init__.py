"""dss14-env: calibrated model and Gymnasium environment of the DSS-14 antenna servo.

The model follows W. Gawronski and R. Bartos, "Modeling and Analysis of the DSS-14 Antenna
Control System", JPL TDA Progress Report 42-124 (1996), called [R] in the docstrings.

Importing the package registers the Gymnasium environments of
:data:`dss14_env.envs.presets.PRESETS` (``DSS14-v0``: track in random gusty wind,
``DSS14-Hold-v0``, ``DSS14-HoldFront-v0``, ``DSS14-HoldSide-v0``, ``DSS14-Step-v0``,
``DSS14-Slew-v0``) and the learning agents' wrapper ids of
:data:`dss14_env.agents.AGENT_ENV_IDS` (``DSS14-Residual-v0``: residual on the report's PI;
``DSS14-ResidualLQG-v0``: residual on the LQG; ``DSS14-KalmanObs-v0``: the policy sees the LQG's
state estimate); nothing is built at import (entry points are strings).

Layers, each importing only those below it: ``core`` <- ``model`` <- ``wind`` <- ``envs`` <-
``baselines`` <- ``agents`` <- ``bench`` / ``reproduce`` <- ``cli`` (``docs/architecture.md``;
checked by ``scripts/check_layers.sh``).  ``dss14_env.cli`` and ``dss14_env.reproduce`` are
modules of the top room: the CLI may import everything, ``reproduce`` everything but the CLI.
"""

__version__ = "0.1.0"


#: matplotlib's built-in non-interactive backends (its ``backend_registry``), always valid
OFF_SCREEN_BACKENDS = frozenset({"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"})


def _set_aside_a_bad_matplotlib_backend() -> None:
    """Importing matplotlib (which the model's control-systems library does) raises when the
    ``MPLBACKEND`` environment variable names no backend; the package draws its figures
    off-screen on Agg (only ``render_mode="human"`` goes through pyplot), so such a value is
    set aside with a warning instead of stopping every command.  The off-screen backends
    matplotlib always ships (:data:`OFF_SCREEN_BACKENDS`) pass without importing it (seconds on
    a loaded machine); any other name is matplotlib's to judge.
    """
    import os
    import sys
    import warnings

    name = os.environ.get("MPLBACKEND")
    if not name or name.lower() in OFF_SCREEN_BACKENDS:
        return
    try:
        import matplotlib  # noqa: F401
    except ValueError:
        del os.environ["MPLBACKEND"]
        for module in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
            del sys.modules[module]  # the half-imported package: imported afresh when needed
        warnings.warn(f"MPLBACKEND={name!r} names no matplotlib backend; ignored (the figures are "
                      f"drawn off-screen)", stacklevel=2)


def _register() -> None:
    from dss14_env.agents import register_agent_envs
    from dss14_env.envs.presets import register_presets

    register_presets()
    register_agent_envs()


_set_aside_a_bad_matplotlib_backend()
_register()
