"""Controllers of the benchmark behind one interface (:mod:`dss14_env.baselines.base`): the
report's PI, the reduced-order LQG, the cvxpy MPC and the H2-optimal yardstick, with their
nominal design model.
"""
