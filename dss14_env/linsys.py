"""Small helpers over python-control state-space objects.

The model blocks are :class:`control.StateSpace` objects with named inputs and outputs; these
helpers evaluate frequency responses fast (one linear solve per frequency) and pick channels
by name.

>>> import control as ct
>>> g = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs=["u"], outputs=["y"])
>>> float(abs(freqresp(g, [0.0], "y", "u")[0]))
1.0
"""

from __future__ import annotations

from typing import Sequence

import control as ct
import numpy as np


def ss(A, B, C, D, inputs: Sequence[str], outputs: Sequence[str], name: str | None = None,
       states: Sequence[str] | None = None) -> ct.StateSpace:
    """Build a continuous-time named :class:`control.StateSpace` (no state elimination)."""
    A = np.atleast_2d(np.asarray(A, float)) if np.size(A) else np.zeros((0, 0))
    n = A.shape[0]
    B = np.asarray(B, float).reshape(n, len(inputs)) if n else np.zeros((0, len(inputs)))
    C = np.asarray(C, float).reshape(len(outputs), n) if n else np.zeros((len(outputs), 0))
    D = np.asarray(D, float).reshape(len(outputs), len(inputs))
    kw = dict(inputs=list(inputs), outputs=list(outputs), name=name)
    if states is not None:
        kw["states"] = list(states)
    return ct.ss(A, B, C, D, remove_useless_states=False, **kw)


def _index(labels: list[str], names: str | Sequence[str] | None) -> list[int]:
    if names is None:
        return list(range(len(labels)))
    if isinstance(names, str):
        names = [names]
    missing = [n for n in names if n not in labels]
    if missing:
        raise KeyError(f"unknown signal(s) {missing}; available: {labels}")
    return [labels.index(n) for n in names]


def channel(sys: ct.StateSpace, outputs: str | Sequence[str] | None = None,
            inputs: str | Sequence[str] | None = None) -> ct.StateSpace:
    """Sub-system from the named inputs to the named outputs (all states kept)."""
    oi = _index(sys.output_labels, outputs)
    ii = _index(sys.input_labels, inputs)
    return ss(sys.A, sys.B[:, ii], sys.C[oi, :], sys.D[np.ix_(oi, ii)],
              [sys.input_labels[i] for i in ii], [sys.output_labels[i] for i in oi],
              states=sys.state_labels)


def freqresp(sys: ct.StateSpace, f_hz, outputs=None, inputs=None) -> np.ndarray:
    """Complex frequency response at the frequencies ``f_hz`` (Hz).

    :return: array of shape ``(len(f_hz),)`` for single channels, otherwise
        ``(len(f_hz), n_outputs, n_inputs)``.
    """
    f = np.atleast_1d(np.asarray(f_hz, float))
    oi = _index(sys.output_labels, outputs)
    ii = _index(sys.input_labels, inputs)
    A, B, C, D = sys.A, sys.B[:, ii], sys.C[oi, :], sys.D[np.ix_(oi, ii)]
    n = A.shape[0]
    out = np.empty((f.size, len(oi), len(ii)), complex)
    eye = np.eye(n)
    for k, fk in enumerate(f):
        s = 2j * np.pi * fk
        out[k] = D + (C @ np.linalg.solve(s * eye - A, B) if n else 0.0)
    if len(oi) == 1 and len(ii) == 1:
        return out[:, 0, 0]
    return out


def is_stable(sys: ct.StateSpace, margin: float = 0.0) -> bool:
    """True if every pole has real part below ``-margin``."""
    return bool(np.all(np.linalg.eigvals(sys.A).real < -margin))
