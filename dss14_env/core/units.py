"""Unit conversions at the edges of the model.

Everything inside ``dss14_env`` is SI (m, kg, s, A, V, Pa, N*m, rad).  The configuration
files keep the report's own units (cm^3, kPa, ...) so that every number can be checked
against the report's tables; :func:`to_si` converts them on load.  Pointing errors leave
the package in millidegrees (mdeg), as the report quotes them.

>>> round(to_si(25.2, "cm^3/rad"), 10)
2.52e-05
>>> round(rad_to_mdeg(1e-3), 3)
57.296
"""

from __future__ import annotations

import math

#: the two axes, in the order of every (az, el) array
AXES = ("az", "el")
#: angle and speed factors at the edges: value_SI = value * factor
DEG = math.pi / 180.0  # deg -> rad
MDEG = math.pi / 180.0e3  # mdeg -> rad
R2D = 180.0 / math.pi  # rad -> deg
R2MD = 180.0e3 / math.pi  # rad -> mdeg
#: km/h in one m/s: the one km/h <-> m/s factor (``v_kmh / KMH_PER_M_S`` is m/s)
KMH_PER_M_S = 3.6
KMH = 1.0 / KMH_PER_M_S  # km/h -> m/s
#: named wind directions relative to the dish, rad (0: into the aperture along the boresight)
WIND_DIRECTIONS = {"front": 0.0, "side": 0.5 * math.pi}

#: unit string -> (SI unit string, factor such that value_SI = factor * value)
UNITS: dict[str, tuple[str, float]] = {
    "1": ("1", 1.0),
    "s": ("s", 1.0),
    "Hz": ("Hz", 1.0),
    "rad/s": ("rad/s", 1.0),
    "rad": ("rad", 1.0),
    "deg": ("rad", DEG),
    "deg/s": ("rad/s", DEG),
    "deg/s^2": ("rad/s^2", DEG),
    "1/s": ("1/s", 1.0),
    "1/s^2": ("1/s^2", 1.0),
    "mdeg": ("rad", MDEG),
    "m": ("m", 1.0),
    "m^2": ("m^2", 1.0),
    "kg/m^3": ("kg/m^3", 1.0),
    "kg": ("kg", 1.0),
    "kg*m^2": ("kg*m^2", 1.0),
    "N/m": ("N/m", 1.0),
    "N*m/rad": ("N*m/rad", 1.0),
    "N*m": ("N*m", 1.0),
    "V/(rad/s)": ("V/(rad/s)", 1.0),
    "A/V": ("A/V", 1.0),
    "A/(rad/s)": ("A/(rad/s)", 1.0),
    "Pa": ("Pa", 1.0),
    "kPa": ("Pa", 1.0e3),
    "kPa*s": ("Pa*s", 1.0e3),
    "Pa*s": ("Pa*s", 1.0),
    "m^3": ("m^3", 1.0),
    "cm^3": ("m^3", 1.0e-6),
    "in^3": ("m^3", 16.387064e-6),
    "cm^3/rad": ("m^3/rad", 1.0e-6),
    "m^3/rad": ("m^3/rad", 1.0),
    "cm^3/s/A": ("m^3/s/A", 1.0e-6),
    "in^3/s/A": ("m^3/s/A", 16.387064e-6),
    "m^3/s/A": ("m^3/s/A", 1.0),
    "cm^3/s/kPa": ("m^3/s/Pa", 1.0e-9),
    "m^3/s/Pa": ("m^3/s/Pa", 1.0),
    "km/h": ("m/s", KMH),
    "m/s": ("m/s", 1.0),
}


def to_si(value: float, unit: str) -> float:
    """Convert ``value`` given in ``unit`` to SI.

    :param value: the number in the given unit
    :param unit: a key of :data:`UNITS`
    :return: the value in the SI unit ``UNITS[unit][0]``
    :raises KeyError: if the unit is unknown
    """
    return float(value) * UNITS[unit][1]


def si_unit(unit: str) -> str:
    """SI unit that ``unit`` converts to (``KeyError`` if unknown)."""
    return UNITS[unit][0]


def rad_to_mdeg(x):
    """Radians to millidegrees (works on arrays)."""
    return x * R2MD

