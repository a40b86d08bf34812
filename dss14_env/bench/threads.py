"""BLAS threads of numpy and scipy while the bench runs (threadpoolctl).

The bench's matrices are small (at most 132 states, a few hundred rows of a batch); with two
threads on two busy cores OpenBLAS spends its time waiting (the yardstick's design took 4 s
instead of 0.1 s when another job shared the machine), and one thread keeps the controllers'
timings steady.  The builds (model, plants, designs) run single-threaded anyway
(:mod:`dss14_env.core.threads`); the thread count here only changes the last bits of the
rollouts' sums, which the quantised encoder could turn into different trajectories (never
different episodes): runs with different counts agree within their confidence intervals.

>>> with blas_threads(1) as bt:
...     bt.n
1
"""

from __future__ import annotations

from typing import Any


class blas_threads:
    """Context manager: run with ``n`` OpenBLAS threads in numpy's and scipy's BLAS, restored
    on exit.

    numpy and scipy each bundle an OpenBLAS; both are limited.

    :param n: threads, default 1; None: unchanged
    """

    def __init__(self, n: int | None = 1) -> None:
        self.n = n
        self.n_libraries = 0
        self._limiter: Any = None

    def __enter__(self) -> blas_threads:
        if self.n is None:
            return self
        import numpy  # noqa: F401  (load both BLAS libraries first)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        blas = ThreadpoolController().select(user_api="blas")
        self.n_libraries = len(blas.lib_controllers)
        self._limiter = blas.limit(limits=int(self.n))
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._limiter is not None:
            self._limiter.restore_original_limits()
            self._limiter = None

    def record(self) -> dict[str, Any]:
        """For results.json: the threads asked for and the BLAS libraries set."""
        return {"threads": self.n, "libraries_set": self.n_libraries}
