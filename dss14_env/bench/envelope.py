"""The Ka-band wind envelope: up to which mean wind a controller keeps the pointing requirement.

The DSN's Ka-band requirement is a mean radial pointing error of 1.54 mdeg, i.e. 1.23 mdeg rms
in elevation and in cross-elevation (Gawronski & Gudim, "Design and Performance of the Monopulse
Control System", TMO Progress Report 42-137, 1999).  For a radial error of two independent
zero-mean Gaussian axes of equal rms ``sigma`` (a Rayleigh distribution) the mean radial error
is ``sigma sqrt(pi / 2)``, which is how 1.54 becomes 1.23.  The X-band value beside it is derived
the same way from the 8-mdeg X-band pointing requirement, taken as a mean radial error:
``8 / sqrt(pi / 2) = 6.38`` mdeg rms per axis.

A controller keeps a requirement at a wind speed when its pooled rms pointing error (the bench's
``pointing_error_mdeg`` rms, the mean included, pooled over the episodes as a root mean square)
is at most the per-axis value on both axes.  Its *envelope* in one direction is the highest
speed up to which it keeps it at every swept speed: linearly interpolated between the last
swept speed that keeps it and the first that does not; the lowest swept speed (``"below"``) if
it fails there, the highest (``"above"``) if it never fails.  The worst direction's envelope is
the smallest over the swept directions.  Confidence intervals: percentile bootstrap, the
episodes of every (direction, speed) point resampled independently, the envelope recomputed per
resample (the worst direction's as the minimum of the same resample's directions).

>>> round(KA_RMS_MDEG, 3), round(X_RMS_MDEG, 2)
(1.229, 6.38)
>>> crossing_speed([30.0, 40.0, 50.0], [0.8, 1.0, 1.4], 1.2)
(45.0, 'within')
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: the DSN's Ka-band pointing requirement, mean radial error, mdeg (TMO PR 42-137)
KA_MEAN_RADIAL_MDEG = 1.54
#: the X-band pointing requirement taken as a mean radial error, mdeg
X_MEAN_RADIAL_MDEG = 8.0
#: mean radial error per unit rms per axis of a circular Gaussian (Rayleigh) error
MEAN_RADIAL_PER_AXIS_RMS = math.sqrt(math.pi / 2.0)
#: the requirements per axis, rms mdeg
KA_RMS_MDEG = KA_MEAN_RADIAL_MDEG / MEAN_RADIAL_PER_AXIS_RMS
X_RMS_MDEG = X_MEAN_RADIAL_MDEG / MEAN_RADIAL_PER_AXIS_RMS
#: the requirements by band
REQUIREMENTS_RMS_MDEG = {"Ka": KA_RMS_MDEG, "X": X_RMS_MDEG}
#: the pointing axes
POINTING_AXES = ("el", "xel")


def crossing_speed(speeds: Sequence[float], worst_rms: Sequence[float], limit: float) -> tuple[float, str]:
    """The envelope of one direction (module docstring) from the worse axis' rms per speed.

    :param speeds: swept speeds, increasing, km/h
    :param worst_rms: the larger of the two axes' pooled rms per speed, mdeg
    :param limit: the requirement, rms mdeg
    :return: ``(speed, where)``: ``where`` is ``"within"`` (interpolated), ``"below"`` (fails at
        the lowest speed) or ``"above"`` (keeps it at every speed)
    """
    if worst_rms[0] > limit:
        return float(speeds[0]), "below"
    for i in range(1, len(speeds)):
        if worst_rms[i] > limit:
            v0, v1, r0, r1 = speeds[i - 1], speeds[i], worst_rms[i - 1], worst_rms[i]
            return float(v0 + (v1 - v0) * (limit - r0) / (r1 - r0)), "within"
    return float(speeds[-1]), "above"


def _pooled(ms: np.ndarray) -> np.ndarray:
    """Pooled rms of episodes from their mean squares ``(..., episodes, axes)``."""
    return np.sqrt(ms.mean(axis=-2))


def envelope(points: Mapping[str, Mapping[float, np.ndarray]], limit: float,
             rng: np.random.Generator, n_resamples: int = 1000, level: float = 0.95) -> dict[str, Any]:
    """The envelopes of one controller.

    :param points: per direction, per speed (km/h) the episodes' rms pointing errors ``(n, 2)``
        ``[el, xel]``, mdeg
    :param limit: the requirement, rms mdeg per axis
    :param rng: the bootstrap's generator
    :return: per direction ``{"speeds_kmh", "rms_mdeg": {el, xel}, "envelope_kmh": {"value",
        "where", "ci95"}}`` and ``"worst"``: ``{"direction", "envelope_kmh"}``
    """
    out: dict[str, Any] = {}
    boot: dict[str, np.ndarray] = {}
    q = (0.5 * (1.0 - level), 0.5 * (1.0 + level))
    for d, by_speed in points.items():
        speeds = sorted(by_speed)
        ms = [np.asarray(by_speed[v], float) ** 2 for v in speeds]
        rms = np.array([_pooled(m) for m in ms])
        value, where = crossing_speed(speeds, rms.max(axis=1).tolist(), limit)
        res = np.array([_pooled(m[rng.integers(0, len(m), (n_resamples, len(m)))]) for m in ms])
        worst = res.max(axis=2)  # (speeds, resamples)
        boot[d] = np.array([crossing_speed(speeds, worst[:, b].tolist(), limit)[0]
                            for b in range(n_resamples)])
        out[d] = {"speeds_kmh": speeds,
                  "rms_mdeg": {ax: rms[:, i].tolist() for i, ax in enumerate(POINTING_AXES)},
                  "envelope_kmh": {"value": value, "where": where,
                                   "ci95": np.quantile(boot[d], q).tolist()}}
    if out:
        d = min(out, key=lambda k: out[k]["envelope_kmh"]["value"])
        low = np.min(np.stack(list(boot.values())), axis=0)
        out["worst"] = {"direction": d, "envelope_kmh": {**out[d]["envelope_kmh"],
                                                         "ci95": np.quantile(low, q).tolist()}}
    return out


def envelope_points(episodes: Sequence[Mapping[str, Any]], points: Sequence[tuple[str, str, float]]
                    ) -> dict[str, dict[str, dict[float, np.ndarray]]]:
    """The episodes' rms pointing errors per controller, direction and speed.

    :param episodes: runner episodes (``controller``, ``scenario``, ``pointing_error_mdeg``)
    :param points: ``(scenario name, direction, speed km/h)`` of the sweep's points
    :return: ``{controller: {direction: {speed: (n, 2) [el, xel] rms, mdeg}}}``
    """
    where = {name: (d, float(v)) for name, d, v in points}
    out: dict[str, dict[str, dict[float, list]]] = {}
    for ep in episodes:
        if ep["scenario"] not in where:
            continue
        d, v = where[ep["scenario"]]
        pe = ep["pointing_error_mdeg"]
        row = [pe[ax]["rms"] for ax in POINTING_AXES]
        if all(math.isfinite(x) for x in row):
            out.setdefault(ep["controller"], {}).setdefault(d, {}).setdefault(v, []).append(row)
    return {c: {d: {v: np.array(r) for v, r in sp.items()} for d, sp in ds.items()} for c, ds in out.items()}


def band_envelopes(episodes: Sequence[Mapping[str, Any]], points: Sequence[tuple[str, str, float]],
                   seed: int = 0, n_resamples: int = 1000) -> dict[str, Any]:
    """The Ka and X envelopes of every controller (:func:`envelope`), with the requirements.

    :return: ``{"requirements_rms_mdeg": {Ka, X}, "mean_radial_mdeg": {Ka, X}, "controllers":
        {name: {band: envelope}}}``
    """
    pts = envelope_points(episodes, points)
    ctrl = {c: {band: envelope(p, limit, np.random.default_rng([seed, i, j]), n_resamples)
                for j, (band, limit) in enumerate(REQUIREMENTS_RMS_MDEG.items())}
            for i, (c, p) in enumerate(pts.items())}
    return {"requirements_rms_mdeg": dict(REQUIREMENTS_RMS_MDEG),
            "mean_radial_mdeg": {"Ka": KA_MEAN_RADIAL_MDEG, "X": X_MEAN_RADIAL_MDEG},
            "controllers": ctrl}


def envelope_table(env: Mapping[str, Any]) -> str:
    """Markdown: per controller the Ka and X envelopes, km/h, front / side / worst, with their
    95 % intervals (``<v`` below the swept range, ``>v`` above it).
    """
    def cell(e: Mapping[str, Any]) -> str:
        v, w, (lo, hi) = e["value"], e["where"], e["ci95"]
        mark = {"below": "<", "above": ">", "within": ""}[w]
        return f"{mark}{v:.0f} ({lo:.0f}–{hi:.0f})"

    dirs = [d for d in ("front", "side") if any(d in b.get("Ka", {}) for b in env["controllers"].values())]
    head = ["controller"] + [f"{band} {d}" for band in ("Ka", "X") for d in (*dirs, "worst")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c, bands in env["controllers"].items():
        row = [c]
        for band in ("Ka", "X"):
            b = bands[band]
            row += [cell(b[d]["envelope_kmh"]) if d in b else "—" for d in dirs]
            w = b.get("worst")
            row.append(f"{cell(w['envelope_kmh'])} {w['direction']}" if w else "—")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)
