"""The calibrated linear model of the DSS-14 servo ([R] Sections II-V).

Blocks (board, hydraulics, gearbox, drive, structure, reduction, loops), their calibration to
the report's figures, the assembled model and the parameter uncertainty.

May import: ``core`` (``docs/architecture.md``).

>>> from dss14_env.model import default_model
>>> default_model().rate_loop.nstates
60
"""

from typing import Any

__all__ = ["DSS14Model", "build_model", "default_model"]


def __getattr__(name: str) -> Any:
    """The assembled model's names, imported on first use: a module that needs only a light
    submodule (e.g. :mod:`dss14_env.model.variants`) does not load the model's dependencies.
    """
    if name in __all__:
        from dss14_env.model import assembly
        return getattr(assembly, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
