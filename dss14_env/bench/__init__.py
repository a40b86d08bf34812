"""``dss14 bench`` and ``dss14 campaign``: the catalog of controllers and scenarios, the plan,
the one runner that scores every controller the same way, statistics, reports and figures,
and the wind direction and speed grid.

May import: ``agents``, ``baselines``, ``envs``, ``wind``, ``model``, ``core``; never
``reproduce`` or ``cli`` (``docs/architecture.md``).
"""
