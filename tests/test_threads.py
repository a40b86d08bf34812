"""Model, wind-load and controller builds are bit-for-bit the same whatever the caller's BLAS
threads (:mod:`dss14_env.core.threads`)."""

from __future__ import annotations

import sys
import types

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from dss14_env.baselines.design import build_design_model
from dss14_env.core.threads import blas_controller, single_threaded
from dss14_env.model.assembly import build_model
from dss14_env.wind.loads import calibrate_wind_loads


def _build(threads: int):
    with threadpool_limits(limits=threads):
        m = build_model()
        loads = calibrate_wind_loads(m)
        dm = build_design_model(0.02, order=18, model=m, loads=loads)
    return m, loads, dm


def test_builds_do_not_depend_on_the_callers_threads() -> None:
    (m1, l1, d1), (m2, l2, d2) = _build(1), _build(2)
    assert np.array_equal(m1.rate_loop.A, m2.rate_loop.A)
    assert np.array_equal(l1.c_front, l2.c_front) and np.array_equal(l1.c_side, l2.c_side)
    assert np.array_equal(d1.Ad, d2.Ad) and np.array_equal(d1.Qd, d2.Qd)


def test_the_callers_limits_come_back() -> None:
    @single_threaded
    def inner() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    with threadpool_limits(limits=2):
        before = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
        assert set(inner()) == {1}
        after = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    assert before == after


def test_the_blas_controller_is_found_again_only_after_an_import() -> None:
    first = blas_controller()
    assert blas_controller() is first  # nothing imported since: not searched again
    sys.modules["_dss14_threads_probe"] = types.ModuleType("_dss14_threads_probe")
    try:
        again = blas_controller()
        assert again is not first
        assert {c.user_api for c in again.lib_controllers} >= {"blas"}
    finally:
        del sys.modules["_dss14_threads_probe"]
