"""The calibrated linear model of the DSS-14 servo ([R] Sections II-V).

Blocks (board, hydraulics, gearbox, drive, structure, reduction, loops), their calibration to
the report's figures, the assembled model and the parameter uncertainty.

May import: ``core`` (``docs/architecture.md``).

>>> from dss14_env.model import default_model
>>> default_model().rate_loop.nstates
60
"""

from dss14_env.model.assembly import DSS14Model, build_model, default_model

__all__ = ["DSS14Model", "build_model", "default_model"]
