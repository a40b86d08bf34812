"""The options of ``dss14 campaign``: a :class:`CampaignSpec` (everything that determines a
campaign's episodes), its wind :class:`Condition` s and their checks.

The campaign (:mod:`dss14_env.bench.campaign`) and its report
(:mod:`dss14_env.bench.campaign_report`) both read the spec from here.

>>> CampaignSpec(controllers=("pi_kp1",), plants=2, directions=("side",), steps=300).conditions[0].key
'50kmh_side'
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from dss14_env.bench import catalog
from dss14_env.bench.catalog import ControllerRow
from dss14_env.bench.plan import MIN_SCORED_S, check_names, control_period, least_steps, parse_wind_speeds
from dss14_env.core.counts import MAX_EPISODE_STEPS, MAX_FIRST_PLANT, MAX_PLANTS, check_count
from dss14_env.core.units import DEG, WIND_DIRECTIONS

#: the controllers of a campaign by default (the catalog's campaign rows)
DEFAULT_CONTROLLERS = catalog.controller_names("campaign")
DEFAULT_PLANTS = 200
DEFAULT_WIND_SPEEDS_KMH = (50.0,)
DEFAULT_DIRECTIONS = ("front", "side")
#: episode length by default, control periods (50 per second): 30 s, of which the first
#: :data:`WARMUP_S` are left out -- long enough for a 3-sigma over many gust time constants,
#: short enough for 200 plants x 3 controllers x 2 directions in minutes
DEFAULT_STEPS = 1500
WARMUP_S = 5.0
DEFAULT_CHUNK_SIZE = 5
#: files and folders a campaign writes into its output folder
OWNED = ("campaign.json", "chunks", "results.json", "results.md", "cdf_*.png")
#: the command its output folders belong to (their manifest's)
COMMAND = "campaign"
#: version of the chunk and campaign file layout
FORMAT = 1


class CampaignOptionError(ValueError):
    """A bad campaign option; the message starts with the option's name."""


def known_controllers() -> tuple[str, ...]:
    """The controllers a campaign knows: every row of :data:`dss14_env.bench.catalog.CONTROLLERS`."""
    return catalog.controller_names()




@dataclass(frozen=True)
class Condition:
    """One wind condition: mean speed (km/h) and direction (``"front"``, ``"side"`` or degrees
    from the boresight).
    """

    speed_kmh: float
    direction: str | float

    @property
    def key(self) -> str:
        d = self.direction if isinstance(self.direction, str) else f"{self.direction:g}deg"
        return f"{self.speed_kmh:g}kmh_{d}"

    @property
    def label(self) -> str:
        d = self.direction if isinstance(self.direction, str) else f"{self.direction:g}°"
        return f"{self.speed_kmh:g} km/h {d}"

    def env_keys(self) -> dict[str, Any]:
        """The environment keys of this condition's hold episodes."""
        d = self.direction if isinstance(self.direction, str) else float(self.direction) * DEG
        return {"scenario": "hold", "wind_speed_kmh": float(self.speed_kmh), "wind_direction": d}


@dataclass(frozen=True)
class CampaignSpec:
    """Everything that determines a campaign's episodes (its chunks depend on nothing else).

    :param controllers: names of :func:`known_controllers`
    :param plants: number of plants
    :param first_plant: index of the first plant (plants ``first_plant`` ... ``+ plants - 1``)
    :param wind_speeds_kmh: mean wind speeds, km/h
    :param directions: wind directions, ``"front"``, ``"side"`` or degrees from the boresight
    :param steps: control periods per episode
    :param warmup_s: seconds at the start left out of the statistics
    :param chunk_size: plants per chunk (one work item)
    :param ppo_model: the ``ppo`` policy (None: the shipped one)
    :param condition_on_pi: draw the plants conditioned on the report's PI (kp 1) being stable
        with margin, as the environment's ``randomize_params`` does (default); False: every
        plant with a stable drive (rate loop), so a controller unstable on one is a finding
        (:func:`dss14_env.model.uncertainty.draw_params`)
    """

    controllers: tuple[str, ...] = DEFAULT_CONTROLLERS
    plants: int = DEFAULT_PLANTS
    first_plant: int = 0
    wind_speeds_kmh: tuple[float, ...] = DEFAULT_WIND_SPEEDS_KMH
    directions: tuple[str | float, ...] = DEFAULT_DIRECTIONS
    steps: int = DEFAULT_STEPS
    warmup_s: float = WARMUP_S
    chunk_size: int = DEFAULT_CHUNK_SIZE
    ppo_model: str | None = None
    format: int = field(default=FORMAT)
    condition_on_pi: bool = True

    def __post_init__(self) -> None:
        for name in ("controllers", "wind_speeds_kmh", "directions"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check_spec(self)
        # numbers as floats, so that the options and their fingerprint survive a JSON round trip
        object.__setattr__(self, "wind_speeds_kmh", tuple(float(s) for s in self.wind_speeds_kmh))
        object.__setattr__(self, "directions", tuple(d if isinstance(d, str) else float(d)
                                                     for d in self.directions))
        object.__setattr__(self, "warmup_s", float(self.warmup_s))

    @property
    def conditions(self) -> list[Condition]:
        """Speeds x directions, in this order."""
        return [Condition(s, d) for s in self.wind_speeds_kmh for d in self.directions]

    @property
    def plant_indices(self) -> list[int]:
        return list(range(self.first_plant, self.first_plant + self.plants))

    def chunks(self) -> list[list[int]]:
        """The plants of each chunk: consecutive runs of ``chunk_size``."""
        k = self.plant_indices
        return [k[i:i + self.chunk_size] for i in range(0, len(k), self.chunk_size)]

    def rows(self) -> tuple[ControllerRow, ...]:
        """The catalog rows of ``controllers``; with ``ppo_model``, the
        :data:`~dss14_env.bench.catalog.POLICY_OPTION_ROW` row is that policy under its own name.
        """
        return tuple(catalog.policy_row(self.ppo_model)
                     if n == catalog.POLICY_OPTION_ROW and self.ppo_model is not None
                     else catalog.CONTROLLERS[n] for n in self.controllers)

    @property
    def names(self) -> tuple[str, ...]:
        """The controllers' names in the results (:meth:`rows`)."""
        return tuple(r.name for r in self.rows())

    @property
    def n_episodes(self) -> int:
        return self.plants * len(self.conditions) * len(self.controllers)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (``campaign.json``)."""
        d = asdict(self)
        for name in ("controllers", "wind_speeds_kmh", "directions"):
            d[name] = list(d[name])
        if self.condition_on_pi:  # the default keeps the fingerprint of campaigns before the option
            del d["condition_on_pi"]
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CampaignSpec:
        known = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(d) - known)
        if unknown:
            raise CampaignOptionError(f"campaign options: unknown keys {unknown}")
        return cls(**dict(d))

    def fingerprint(self) -> str:
        """SHA-256 of the canonical JSON of :meth:`as_dict` (stamped on every chunk file)."""
        text = json.dumps(self.as_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _positive_int(v: Any, option: str, lo: int = 1, hi: int = MAX_PLANTS) -> int:
    return check_count(v, option, lo, hi, CampaignOptionError)


def _check_controllers(names: Sequence[str]) -> None:
    check_names(names, known_controllers(), "--controllers", "controller", CampaignOptionError)


def check_policy(spec: CampaignSpec) -> None:
    """Refuse a learned controller's policy that cannot act on a DSS14 environment (missing
    path, unreadable files, another environment's sizes) before any work.

    :raises CampaignOptionError: one line naming the option and the problem
    """
    for name, row in zip(spec.controllers, spec.rows(), strict=True):
        problem = row.policy_problem()
        if problem is not None:
            opt = ("--ppo-model" if name == catalog.POLICY_OPTION_ROW and spec.ppo_model is not None
                   else f"--controllers {name}")
            raise CampaignOptionError(f"{opt}: {problem}")


def _check_directions(directions: Sequence[str | float]) -> None:
    """Refuse an empty, unknown or repeated ``--directions``."""
    if not directions:
        raise CampaignOptionError("--directions: give at least one direction")
    for d in directions:
        ok = d in WIND_DIRECTIONS if isinstance(d, str) else (
            not isinstance(d, bool) and isinstance(d, (int, float)) and math.isfinite(d) and 0 <= d < 360)
        if not ok:
            raise CampaignOptionError(f"--directions: 'front', 'side' or degrees in [0, 360), got {d!r}")
    degrees = [math.degrees(WIND_DIRECTIONS[d]) if isinstance(d, str) else float(d) for d in directions]
    if len(set(degrees)) != len(degrees):  # 'front' and 0 are one direction
        raise CampaignOptionError(f"--directions: a direction is repeated: {list(directions)} "
                                  f"are {', '.join(f'{x:g}' for x in degrees)} degrees")


def check_spec(spec: CampaignSpec) -> None:
    """Raise :class:`CampaignOptionError` naming the first bad option."""
    _check_controllers(spec.controllers)
    _positive_int(spec.plants, "--plants")
    _positive_int(spec.first_plant, "--first-plant", 0, MAX_FIRST_PLANT)
    _positive_int(spec.steps, "--steps", 1, MAX_EPISODE_STEPS)
    _positive_int(spec.chunk_size, "--chunk-size")
    parse_wind_speeds(spec.wind_speeds_kmh, CampaignOptionError, hint="")
    _check_directions(spec.directions)
    if not isinstance(spec.condition_on_pi, bool):
        raise CampaignOptionError(f"condition_on_pi: must be true or false, got {spec.condition_on_pi!r}")
    w = spec.warmup_s
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not (math.isfinite(w) and w >= 0):
        raise CampaignOptionError(f"warmup_s: must be a finite number >= 0, got {w!r}")
    dt = control_period()
    if spec.steps < least_steps(w, dt):
        raise CampaignOptionError(f"--steps: {spec.steps} steps ({dt:g} s each) leave less than "
                                  f"{MIN_SCORED_S:g} s after the {w:g}-s warm-up; give --steps "
                                  f"{least_steps(w, dt)} or more")
    opt_row = catalog.POLICY_OPTION_ROW
    if spec.ppo_model is not None and opt_row not in spec.controllers:
        raise CampaignOptionError(f"--ppo-model: given, but {opt_row!r} is not among --controllers")
    clash = None if spec.ppo_model is None else catalog.policy_name_problem(spec.ppo_model)
    if clash is not None:
        raise CampaignOptionError(f"--ppo-model: {clash}")
    if len(set(spec.names)) != len(spec.names):
        raise CampaignOptionError(f"--ppo-model: the policy's name is a controller's already: "
                                  f"{list(spec.names)}")
    if spec.format != FORMAT:
        raise CampaignOptionError(f"campaign format {spec.format!r} is not {FORMAT}")


def parse_directions(values: Iterable[str | float] | None) -> tuple[str | float, ...] | None:
    """``--directions``: ``front``, ``side`` or a number of degrees (kept as a float)."""
    if values is None:
        return None
    out: list[str | float] = []
    for v in values:
        if isinstance(v, str) and v in WIND_DIRECTIONS:
            out.append(v)
            continue
        try:
            out.append(float(v))
        except (TypeError, ValueError):
            raise CampaignOptionError(f"--directions: 'front', 'side' or degrees, got {v!r}") from None
    return tuple(out)






__all__ = ["CampaignOptionError", "CampaignSpec", "Condition", "DEFAULT_CHUNK_SIZE",
           "DEFAULT_CONTROLLERS", "DEFAULT_DIRECTIONS", "DEFAULT_PLANTS", "DEFAULT_STEPS",
           "DEFAULT_WIND_SPEEDS_KMH", "FORMAT", "WARMUP_S", "check_policy", "check_spec",
           "known_controllers",
           "parse_directions"]
