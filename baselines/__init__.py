"""Controllers of the benchmark behind one interface (:mod:`dss14_env.baselines.base`): the
report's PI, the reduced-order LQG, the cvxpy MPC and the H2-optimal yardstick, with their
nominal design model, and the one episode loop (:mod:`dss14_env.baselines.rollout`).

Installed as ``dss14_env.baselines``.  May import: ``envs``, ``wind``, ``model``, ``core``
(``docs/architecture.md``).
"""
