"""Wind: Davenport gusts (:mod:`dss14_env.wind.gusts`) and the wind loads on the dish with their
calibration to the report's Table 4 (:mod:`dss14_env.wind.loads`).

May import: ``model``, ``core`` (``docs/architecture.md``).
"""

from dss14_env.wind.gusts import davenport_filter, davenport_psd, davenport_variance, generate_gusts

__all__ = ["davenport_filter", "davenport_psd", "davenport_variance", "generate_gusts"]
