"""Model-building numerics that do not depend on the caller's BLAS threads.

OpenBLAS splits matrix products and factorisations over its threads, and the summation order
changes the last bits of the result with the thread count.  The encoder quantiser of the
environments turns such last-bit differences into different trajectories, so a model, a plant or
a controller design built under 2 threads would give other episodes than the same build under
1 thread.  :func:`single_threaded` runs a build with one BLAS thread (the matrices are small: it
is not slower), so every build is bit-for-bit the same whatever the caller's settings.
Finding the BLAS libraries reads the process's memory map (about half a millisecond, more than
the rest of an episode reset), so the controller that :func:`single_threaded` limits through is
found once and found again only after new modules were imported (:func:`blas_controller`).

>>> import numpy as np
>>> @single_threaded
... def gram(a):
...     return a @ a.T
>>> gram(np.eye(2)).tolist()
[[1.0, 0.0], [0.0, 1.0]]
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any, TypeVar

from threadpoolctl import ThreadpoolController

F = TypeVar("F", bound=Callable[..., Any])


def single_threaded(func: F) -> F:
    """Decorator: run ``func`` with the BLAS libraries limited to one thread (restored after).

    The pools are set through their ``threadpoolctl`` library controllers
    (:func:`blas_libraries`), and only those not at one thread already: the same limit as
    ``ThreadpoolController.limit(limits=1, user_api="blas")`` at a tenth of its cost (a plant is
    built at every episode reset).
    """
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        changed = [(lib, n) for lib in blas_libraries() if (n := lib.get_num_threads()) != 1]
        for lib, _ in changed:
            lib.set_num_threads(1)
        try:
            return func(*args, **kwargs)
        finally:
            for lib, n in changed:
                lib.set_num_threads(n)
    return wrapper  # type: ignore[return-value]


def blas_controller() -> ThreadpoolController:
    """The thread pools of the libraries loaded now (``threadpoolctl``), found again only when
    modules were imported since the last call (an import is what loads a new BLAS library).
    """
    return _controller(len(sys.modules))


def blas_libraries() -> tuple:
    """The ``threadpoolctl`` library controllers of the BLAS libraries loaded now (as
    :func:`blas_controller`).
    """
    return _blas_libraries(len(sys.modules))


@functools.lru_cache(maxsize=1)
def _controller(n_modules: int) -> ThreadpoolController:
    """A controller made when ``n_modules`` modules were loaded (the cache key)."""
    return ThreadpoolController()


@functools.lru_cache(maxsize=1)
def _blas_libraries(n_modules: int) -> tuple:
    """The BLAS library controllers of :func:`_controller` for ``n_modules`` modules."""
    return tuple(lib for lib in _controller(n_modules).lib_controllers if lib.user_api == "blas")
