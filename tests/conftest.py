"""Shared test settings: the hypothesis profiles.

About 100 examples per property in the default suite (``dss14-default``); the ``slow`` tests
and ``HYPOTHESIS_PROFILE=dss14-slow`` run 1,000+ (``settings.get_profile("dss14-slow")``).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

_CHECKS = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
settings.register_profile("dss14-default", max_examples=100, deadline=None, suppress_health_check=_CHECKS)
settings.register_profile("dss14-slow", max_examples=1500, deadline=None, suppress_health_check=_CHECKS)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dss14-default"))
