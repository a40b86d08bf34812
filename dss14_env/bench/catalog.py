"""The one catalog of the bench: a row per controller and a row per scenario.

Every list of controllers or scenarios in the package derives from here: the runner's names,
the bench's defaults, budgets and loaded axes, the figures' groups, the ``dss14 bench`` /
``dss14 campaign`` help and choices, the campaign's controller set and the tables of
docs/bench.md.  No name is special: the MPC is a row that runs one episode at a time, the
PPO policies are rows with a ``policy``.

**Add a controller**: its module (a :class:`~dss14_env.baselines.base.Controller` whose
constructor takes the environment) and its row, in :data:`CONTROLLER_ROWS` or, from outside
the package, through :func:`register_controller`.  **Add a scenario**: one row, in
:data:`SCENARIO_ROWS` or through :func:`register_scenario`: its budgets and either the name of
a preset of :data:`dss14_env.envs.presets.PRESETS` (with environment keys on top) or a
:class:`~dss14_env.envs.presets.Preset` of its own.  :data:`CONTROLLERS`, :data:`SCENARIOS`,
the names, help texts and tables read the registered rows when they are used, so a row
registered before ``dss14 bench`` runs (``dss14 --plugin MODULE bench ...`` imports a module
that registers rows) is in every one of them.  docs/bench.md shows a worked example of each.

>>> CONTROLLERS["mpc"].batchable, CONTROLLERS["ppo"].policy
(False, 'residual_pi')
>>> SCENARIOS["hold_side"].loaded_axes, SCENARIOS["step"].group
(('az',), 'move')
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from dss14_env.envs.presets import PRESETS, Preset, register_preset, unregister_preset


@dataclass(frozen=True)
class ControllerRow:
    """One controller of the bench and the campaign.

    :param name: its name in options, tables and results
    :param module: the module of its class (``dss14_env.baselines.lqg``)
    :param cls: the class; built as ``cls(env, *args)`` (a policy row: see ``policy``)
    :param description: one line for the help and the docs
    :param batchable: runs many episodes at once through the vector environment (its class'
        ``batchable``); False: one episode at a time on the first seeds of every scenario
    :param args: positional arguments after the environment (e.g. the PI's gain set)
    :param policy: a trained policy this controller is (with ``shipped``, a shipped policy's
        name of ``agents/policies``, else the path of a folder), loaded by
        :func:`dss14_env.agents.policy.load_policy`; None: a designed controller
    :param shipped: ``policy`` names a shipped policy: a user's path is never looked up among
        them, so a folder of the user's named like one is that folder
    :param config: its section of ``configs/controllers.yaml`` (None: none)
    :param bench: in a bench run without ``--controllers``
    :param campaign: in a campaign without ``--controllers``
    :param sensors: the environment's sensors it needs (``sensors`` of ``configs/env.yaml``):
        the runner gives it the scenario's environment with these
    """

    name: str
    module: str
    cls: str
    description: str
    batchable: bool = True
    args: tuple[Any, ...] = ()
    policy: str | None = None
    shipped: bool = False
    config: str | None = None
    bench: bool = True
    campaign: bool = False
    sensors: tuple[str, ...] = ("encoders",)

    def make(self, env: Any) -> Any:
        """The controller for ``env`` (it reads the environment's interface, never its plant)."""
        if self.policy is not None:
            from dss14_env.agents.policy import load_policy
            return load_policy(self.policy_path(), env=env, name=self.name)
        return getattr(importlib.import_module(self.module), self.cls)(env, *self.args)

    __call__ = make

    def policy_path(self) -> Path | None:
        """The folder of the row's policy (a shipped name resolved), or None."""
        if self.policy is None:
            return None
        if not self.shipped:
            return Path(self.policy)
        from dss14_env.agents.policy import POLICIES_DIR
        return POLICIES_DIR / self.policy

    def policy_label(self) -> str | None:
        """The row's policy as results files name it: ``agents/policies/<name>`` for a shipped
        one (no machine's folder recorded), else its path as given; None without a policy.
        """
        if self.policy is None:
            return None
        return f"agents/policies/{self.policy}" if self.shipped else str(self.policy)

    def policy_problem(self) -> str | None:
        """Why the row's policy cannot act on a DSS14 environment (its files loaded and its
        observation and action sizes checked), or None.
        """
        if self.policy is None:
            return None
        from dss14_env.agents.policy import dss14_policy_problem
        return dss14_policy_problem(self.policy_path())


_POLICY_CLASS = ("dss14_env.agents.policy", "PolicyController")


def _policy_row(name: str, policy: str, description: str, bench: bool = True,
                campaign: bool = True, shipped: bool = True) -> ControllerRow:
    return ControllerRow(name, *_POLICY_CLASS, description, policy=policy, shipped=shipped, bench=bench,
                         campaign=campaign)


#: the controllers, in table order
CONTROLLER_ROWS: tuple[ControllerRow, ...] = (
    ControllerRow("pi_kp1", "dss14_env.baselines.pi", "PIController",
                  "the report's PI, kp 1, ki 0.3 (`baselines/pi.py`); the reference of the ratios",
                  args=("kp1",), campaign=True),
    ControllerRow("pi_kp0.7", "dss14_env.baselines.pi", "PIController",
                  "the report's PI, kp 0.7, ki 0.2", args=("kp0.7",)),
    ControllerRow("lqg", "dss14_env.baselines.lqg", "LQGController",
                  "reduced-order LQG with wind-direction inference (`baselines/lqg.py`)",
                  config="lqg", campaign=True),
    ControllerRow("mpc", "dss14_env.baselines.mpc", "MPCController",
                  "MPC on the same estimator, OSQP (`baselines/mpc.py`)", batchable=False,
                  config="mpc", campaign=True),
    ControllerRow("lqg_pointing", "dss14_env.baselines.lqg", "PointingLQGController",
                  "LQG designed for the dish's true pointing error: Kalman filter on the drive "
                  "encoders, the LQR scores the structure's pointing (deformation included) "
                  "(`baselines/lqg.py`, docs/controllers.md)", config="pointing", campaign=True),
    ControllerRow("lqg_pointing_sched", "dss14_env.baselines.scheduled", "ScheduledPointingLQGController",
                  "lqg_pointing with its gust model and encoder-noise model scheduled on the measured "
                  "mean wind speed (the nearest of a 10-70 km/h grid; `baselines/scheduled.py`)",
                  config="schedule", bench=False),
    ControllerRow("mpc_pointing", "dss14_env.baselines.mpc", "PointingMPCController",
                  "MPC on the pointing LQG's design and estimator, its soft error bound on the "
                  "predicted pointing error (`baselines/mpc.py`)", batchable=False,
                  config="pointing"),
    _policy_row("ppo", "residual_pi", "PPO residual on the report's PI, the policy shipped with the "
                "package (`agents/policies/residual_pi`); `--ppo-model PATH` replaces it by a "
                "trained policy, scored under its own name"),
    _policy_row("ppo_plain", "ppo_plain", "plain PPO, the policy alone sets the command "
                "(`agents/policies/ppo_plain`, docs/rl.md); trained in the holds at ±0.02 °/s, it "
                "cannot follow slews and tracks and terminates in the slew"),
    _policy_row("ppo_residual_lqg", "ppo_residual_lqg", "model-informed PPO, a residual on the LQG "
                "(`agents/policies/ppo_residual_lqg`, docs/rl.md)"),
    _policy_row("ppo_general", "ppo_general", "general model-informed PPO, one policy for every "
                "scenario: a residual on lqg_pointing_sched (designed for each row's encoders and measured "
                "mean wind speed) through a 25-ms "
                "command filter, trained on the pointing error in a mixture of tracks, holds with "
                "drive or axis encoders, steps and slews in wind drawn over 10-70 km/h and "
                "0-180 degrees (`agents/policies/ppo_general`, docs/rl.md)"),
    _policy_row("ppo_general_random", "ppo_general_random", "the general plain PPO trained on "
                "plants drawn from the report's hydraulic ranges (`agents/policies/ppo_general_random`, "
                "docs/rl.md)", bench=False),
    ControllerRow("yardstick", "dss14_env.baselines.yardstick", "YardstickController",
                  "the H2-optimal full-order LQG told the episode's wind (an oracle designed "
                  "without the acceleration limit: limit-cycles on steps and slews and on some "
                  "holds, e.g. front wind seed 3)", bench=False),
    ControllerRow("yardstick_pointing", "dss14_env.baselines.yardstick", "PointingYardstickController",
                  "the pointing yardstick: the H2-optimal full-order LQG for the dish's pointing "
                  "error from the drive encoders, told the episode's wind (an oracle designed "
                  "without the acceleration limit)", bench=False),
    ControllerRow("pi_monopulse", "dss14_env.baselines.monopulse", "PIMonopulseController",
                  "the DSN's arrangement: the report's PI (kp 1) on the encoders inside a monopulse "
                  "loop that integrates the measured pointing error (`baselines/monopulse.py`; "
                  "runs with the monopulse sensor)", config="monopulse", bench=True,
                  sensors=("encoders", "monopulse")),
    ControllerRow("lqg_monopulse", "dss14_env.baselines.monopulse", "MonopulseLQGController",
                  "the pointing LQG with a Kalman filter fusing the encoders and the monopulse "
                  "measurement, integrating the measured pointing error (`baselines/monopulse.py`; "
                  "runs with the monopulse sensor)", config="monopulse", bench=True,
                  sensors=("encoders", "monopulse")),
    ControllerRow("mpc_monopulse", "dss14_env.baselines.monopulse", "MonopulseMPCController",
                  "the pointing MPC on lqg_monopulse's fused estimator and integrator, OSQP "
                  "(`baselines/monopulse.py`; runs with the monopulse sensor)", batchable=False,
                  config="monopulse", bench=False, sensors=("encoders", "monopulse")),
    ControllerRow("yardstick_monopulse", "dss14_env.baselines.monopulse", "MonopulseYardstickController",
                  "the pointing yardstick measuring the drive encoders and the monopulse sensor, told "
                  "the episode's wind (an oracle designed without the acceleration limit)", bench=False,
                  sensors=("encoders", "monopulse")),
)

#: the row that ``--ppo-model`` replaces by the given policy
POLICY_OPTION_ROW = "ppo"


class LiveMapping(Mapping):
    """A read-only mapping computed from the registered rows whenever it is read, so that rows
    registered later are in it (e.g. the loaded axes per scenario).

    :param build: makes the mapping's current content
    """

    def __init__(self, build: Callable[[], Mapping[str, Any]]) -> None:
        self._build = build

    def __getitem__(self, key: str) -> Any:
        return self._build()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._build())

    def __len__(self) -> int:
        return len(self._build())

    def __repr__(self) -> str:
        return f"LiveMapping({dict(self._build())!r})"


#: the registered controller rows by name: :data:`CONTROLLER_ROWS` and those of
#: :func:`register_controller`
_CONTROLLER_REGISTRY: dict[str, ControllerRow] = {r.name: r for r in CONTROLLER_ROWS}
#: controller rows by name (a read-only view of the registered rows)
CONTROLLERS: Mapping[str, ControllerRow] = MappingProxyType(_CONTROLLER_REGISTRY)


def policy_name(path: str | Path) -> str:
    """The name a trained policy scores under: its folder's (``<run>/best`` for a run's
    ``eval/best`` or checkpoint folder, the file's stem for a zip).
    """
    p = Path(path)
    if p.suffix == ".zip":
        p = p.with_suffix("")
    if p.parent.name in ("eval", "checkpoints"):
        return f"{p.parent.parent.name}/{p.name}"
    return p.name or str(path)


def policy_name_problem(path: str | Path) -> str | None:
    """Why the policy at ``path`` cannot score under its name (a catalog controller's, which
    the tables would not tell from it), or None.
    """
    name = policy_name(path)
    if name not in CONTROLLERS:
        return None
    return (f"the policy's name {name!r} (its folder's) is the catalog controller {name!r}'s, "
            f"which the tables would not tell from it; rename the folder (the shipped one is "
            f"--controllers {name})" if CONTROLLERS[name].shipped else
            f"the policy's name {name!r} (its folder's) is a catalog controller's; rename the folder")


def policy_row(path: str | Path, name: str | None = None) -> ControllerRow:
    """A row for the trained policy at ``path`` (``--ppo-model``: always a path, never a shipped
    policy's name), named after the policy (:func:`policy_name`) unless ``name`` is given.
    """
    return _policy_row(name or policy_name(path), str(path), f"trained policy {path}", campaign=False,
                       shipped=False)


@dataclass(frozen=True)
class Budget:
    """Episode length and counts of one scenario.

    :param seconds: episode length, s
    :param episodes: episodes of the controllers that act on batches (seeds 0, 1, ...)
    :param sequential: episodes of the controllers that run one at a time (the first seeds)
    """

    seconds: float
    episodes: int
    sequential: int


@dataclass(frozen=True)
class Scenario:
    """One benchmark scenario as the runner runs it: environment keys, episode length and
    metric window.

    :param env: keyword arguments of :class:`dss14_env.envs.env.DSS14Env`
    :param steps: control periods per episode
    :param warmup_s: seconds at the start left out of the error statistics
    :param description: one line for tables
    :param group: :data:`GROUPS`: ``"wind"`` (scored by the error's 3σ) or ``"move"`` (a
        commanded move, scored by its response: overshoot, settling, peak error and rms after
        settling)
    """

    env: Mapping[str, Any]
    steps: int
    warmup_s: float = 0.0
    description: str = ""
    group: str = "wind"


@dataclass(frozen=True)
class ScenarioRow:
    """One scenario of the bench.

    :param name: its name in options, tables and results (and its preset's,
        :data:`dss14_env.envs.presets.PRESETS`: environment keys, warm-up, loaded axes)
    :param default: the default run's budget (long and many enough for the statistics)
    :param quick: the ``--quick`` budget (the CI smoke test)
    :param steps: episode length of :func:`dss14_env.bench.runner.run` without ``steps``,
        control periods (None: the preset's ``max_episode_steps``)
    :param group: ``"wind"`` (disturbance rejection, scored by the 3σ) or ``"move"``
        (commanded moves, scored by the move's response in the tables and results): the axes
        of errors_3sigma.png
    :param traced: the bench keeps the first seed's time histories (the figures draw them)
    :param sweep: the error-vs-wind sweep's direction this scenario anchors (``"front"``,
        ``"side"``; None: no sweep)
    :param bench: in a bench run without ``--scenarios``
    :param preset: the preset it runs, when not the one of its name (a variant of a preset),
        or a :class:`~dss14_env.envs.presets.Preset` of its own (a scenario in one row;
        :func:`register_scenario` registers its Gymnasium id)
    :param env: environment keys on top of the preset's (e.g. ``{"encoders": "axis"}``)
    :param note: what the variant changes, appended to the preset's description
    """

    name: str
    default: Budget
    quick: Budget
    steps: int | None = None
    group: str = "wind"
    traced: bool = False
    sweep: str | None = None
    bench: bool = True
    preset: str | Preset | None = None
    env: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    note: str = ""

    @property
    def preset_name(self) -> str:
        """The name of the preset it runs (its own name for a preset of its own)."""
        return self.preset if isinstance(self.preset, str) else self.name

    @property
    def preset_spec(self) -> Preset:
        """The preset it runs."""
        return self.preset if isinstance(self.preset, Preset) else PRESETS[self.preset_name]

    @property
    def description(self) -> str:
        """The preset's description, with the variant's note."""
        d = self.preset_spec.description
        return f"{d}; {self.note}" if self.note else d

    @property
    def loaded_axes(self) -> tuple[str, ...]:
        """The axes the scenario's wind loads (its preset's)."""
        return self.preset_spec.loaded_axes

    def scenario(self) -> Scenario:
        """The runner's scenario: the preset's keys (and the variant's), warm-up and description."""
        p = self.preset_spec
        return Scenario({**p.kwargs, **self.env}, self.steps or p.max_episode_steps, p.warmup_s,
                        self.description, self.group)


#: the scenarios, in table order; hold budgets: a 95 % half-width <= 5 % of the loaded axis'
#: 3σ for the batched controllers (60-s episodes scatter about 15 % (1 σ) from seed to seed, so
#: 128 of them give about 2-3 %); the MPCs get 64 in the holds: mpc's pointing xel 3σ² scatters
#: about 70 % (1 σ) from seed to seed, so its half-width, 11-12 % with 36 episodes, is 7 % with
#: 64 (every other MPC cell is below 5 %); the track's random wind makes 3σ² scatter 140-180 %
#: for every controller (128 episodes give 12-16 %, 10 % would take 200-320), and the MPCs get
#: 96 there (64 gave 18-20 %); with the MPC's unconstrained steps solved without a QP it all fits
#: the 5-minute budget on 2 cores with ``--jobs 2`` (a process builds each MPC once)
SCENARIO_ROWS: tuple[ScenarioRow, ...] = (
    ScenarioRow("hold_front", Budget(60.0, 128, 64), Budget(15.0, 8, 1), traced=True, sweep="front"),
    ScenarioRow("hold_side", Budget(60.0, 128, 64), Budget(15.0, 8, 1), traced=True, sweep="side"),
    # no wind: episodes differ only in start and quantisation
    ScenarioRow("step", Budget(20.0, 16, 2), Budget(15.0, 4, 1), steps=1000, group="move", traced=True),
    # random 30-70 km/h wind and direction: wide by design
    ScenarioRow("track", Budget(40.0, 128, 96), Budget(10.0, 8, 1)),
    # the commanded move dominates
    ScenarioRow("slew", Budget(50.0, 32, 2), Budget(10.0, 4, 1), steps=2500, group="move"),
    # the report's encoders close to the axes: the batched controllers only (the MPCs' budget is
    # the drive-encoder holds')
    ScenarioRow("hold_front_axis", Budget(60.0, 64, 0), Budget(15.0, 4, 0), preset="hold_front",
                env={"encoders": "axis"}, note="axis encoders (the structure's angles at the axes)"),
    ScenarioRow("hold_side_axis", Budget(60.0, 64, 0), Budget(15.0, 4, 0), preset="hold_side",
                env={"encoders": "axis"}, note="axis encoders (the structure's angles at the axes)"),
)

#: the registered scenario rows by name: :data:`SCENARIO_ROWS` and those of :func:`register_scenario`
_SCENARIO_REGISTRY: dict[str, ScenarioRow] = {r.name: r for r in SCENARIO_ROWS}
#: the Gymnasium id each registered scenario's own preset added (removed with the scenario)
_SCENARIO_IDS: dict[str, str] = {}
#: scenario rows by name (a read-only view of the registered rows)
SCENARIOS: Mapping[str, ScenarioRow] = MappingProxyType(_SCENARIO_REGISTRY)


def with_row(rows: tuple[Any, ...], row: Any) -> tuple[Any, ...]:
    """``rows`` with ``row`` replacing the one of its name (or appended)."""
    names = [r.name for r in rows]
    if row.name in names:
        return tuple(row if r.name == row.name else r for r in rows)
    return (*rows, row)


def controller_names(which: str | None = None) -> tuple[str, ...]:
    """Controller names: all (``which`` None), or those of a run without ``--controllers``
    (``"bench"``, ``"campaign"``).
    """
    return tuple(r.name for r in CONTROLLERS.values() if which is None or getattr(r, which))


def scenario_names(which: str | None = None) -> tuple[str, ...]:
    """Scenario names: all, or those of a bench run without ``--scenarios`` (``"bench"``)."""
    return tuple(r.name for r in SCENARIOS.values() if which is None or getattr(r, which))


def choices_help(names: tuple[str, ...], default: tuple[str, ...]) -> str:
    """An option's help: the names, and which are the default."""
    left = [n for n in names if n not in default]
    tail = "all" if not left else f"all but {' '.join(left)}"
    return f"{' '.join(names)} (default: {tail})"


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def controllers_table() -> str:
    """The markdown table of the controller rows (docs/bench.md)."""
    lines = ["| name | controller | how it runs | default in bench / campaign |", "|---|---|---|---|"]
    for r in CONTROLLERS.values():
        runs = "batched" if r.batchable else "one episode at a time"
        lines.append(f"| `{r.name}` | {r.description} | {runs} | {_yes(r.bench)} / {_yes(r.campaign)} |")
    return "\n".join(lines) + "\n"


def scenarios_table() -> str:
    """The markdown table of the scenario rows (docs/bench.md): what each runs by default
    (batched episodes, one-at-a-time episodes) and with ``--quick``.
    """
    lines = ["| name | what | episode | batched episodes | one-at-a-time episodes | `--quick` |",
             "|---|---|---|---|---|---|"]
    for r in SCENARIOS.values():
        p, d, q = r.preset_spec, r.default, r.quick
        warm = f", {p.warmup_s:g} s warm-up" if p.warmup_s else ""
        lines.append(f"| `{r.name}` | {r.description} | {d.seconds:g} s{warm} | {d.episodes} | "
                     f"{d.sequential} | {q.seconds:g} s x {q.episodes} ({q.sequential}) |")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ registration
_NAME_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.-")
#: the groups of errors_3sigma.png a scenario can be in
GROUPS = ("wind", "move")


def _check_new_name(name: Any, registry: Mapping[str, Any], what: str) -> None:
    if not isinstance(name, str) or not name or not set(name) <= _NAME_CHARS:
        raise ValueError(f"{what} name: letters, digits, '_', '.' and '-' only, got {name!r}")
    if name in registry:
        raise ValueError(f"{what} {name!r} is registered already")


def register_controller(row: ControllerRow) -> ControllerRow:
    """Add a controller to the catalog from outside the package (a plugin module, a test): it
    is then in :data:`CONTROLLERS`, the names, the help and the tables, and ``dss14 bench
    --controllers NAME`` runs it.  Checked before it is added: a free name, and a class that
    imports and, for a ``batchable`` row, acts on batches.

    :param row: the controller's row (``module`` and ``cls`` name its class)
    :return: the row
    :raises ValueError: naming what is wrong
    """
    if not isinstance(row, ControllerRow):
        raise ValueError(f"register_controller: a ControllerRow, got {type(row).__name__}")
    _check_new_name(row.name, CONTROLLERS, "controller")
    if row.policy is None:
        try:
            cls = getattr(importlib.import_module(row.module), row.cls)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"controller {row.name!r}: {row.module}.{row.cls} cannot be imported "
                             f"({exc})") from None
        if row.batchable and not getattr(cls, "batchable", False):
            raise ValueError(f"controller {row.name!r}: {row.cls} does not act on batches (its "
                             f"batchable is False); give the row batchable=False")
    _CONTROLLER_REGISTRY[row.name] = row
    return row


def register_scenario(row: ScenarioRow) -> ScenarioRow:
    """Add a scenario to the catalog from outside the package: one row, with a preset of its
    own or a shipped preset's name.  It is then in :data:`SCENARIOS`, the names, the help and
    the tables, and ``dss14 bench --scenarios NAME`` runs it; a preset of its own has its
    Gymnasium id registered.  Checked before it is added: a free name, a known preset, budgets
    of at least one episode, a known group, no wind-sweep anchor (the shipped holds are the
    sweep's), and environment keys the environment accepts.

    :param row: the scenario's row
    :return: the row
    :raises ValueError: naming what is wrong
    """
    if not isinstance(row, ScenarioRow):
        raise ValueError(f"register_scenario: a ScenarioRow, got {type(row).__name__}")
    _check_new_name(row.name, SCENARIOS, "scenario")
    what = f"scenario {row.name!r}"
    if isinstance(row.preset, str) and row.preset not in PRESETS:
        raise ValueError(f"{what}: unknown preset {row.preset!r}; known: {', '.join(PRESETS)}")
    for label, b in (("default", row.default), ("quick", row.quick)):
        ok = isinstance(b, Budget) and b.seconds > 0 and b.episodes >= 1
        if not (ok and 0 <= b.sequential <= b.episodes):
            raise ValueError(f"{what}: {label} budget: seconds > 0, episodes >= 1 and 0 <= sequential "
                             f"<= episodes, got {b!r}")
    if row.group not in GROUPS:
        raise ValueError(f"{what}: group is one of {GROUPS}, got {row.group!r}")
    if row.sweep is not None:
        raise ValueError(f"{what}: sweep: the wind sweep extends the shipped holds; give sweep=None")
    from dss14_env.envs.config import load_env_config  # (the environment, loaded when used)

    sc = row.scenario()
    try:
        load_env_config(**dict(sc.env))
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    if isinstance(row.preset, Preset) and register_preset(row.preset):
        _SCENARIO_IDS[row.name] = row.preset.env_id
    _SCENARIO_REGISTRY[row.name] = row
    return row


def unregister(name: str) -> None:
    """Remove a controller or scenario that :func:`register_controller` or
    :func:`register_scenario` added, with the Gymnasium id its own preset added (a shipped row
    stays).

    :raises ValueError: a shipped row's name, or a name not registered
    """
    shipped = {r.name for r in CONTROLLER_ROWS} | {r.name for r in SCENARIO_ROWS}
    if name in shipped:
        raise ValueError(f"{name!r} is a shipped row; only registered rows can be removed")
    for registry in (_CONTROLLER_REGISTRY, _SCENARIO_REGISTRY):
        if name in registry:
            del registry[name]
            if name in _SCENARIO_IDS:
                unregister_preset(_SCENARIO_IDS.pop(name))
            return
    raise ValueError(f"{name!r} is not a registered controller or scenario")


def replace_steps(sc: Scenario, steps: int) -> Scenario:
    """``sc`` with another episode length."""
    return dataclasses.replace(sc, steps=int(steps))


__all__ = ["Budget", "CONTROLLERS", "CONTROLLER_ROWS", "ControllerRow", "GROUPS", "LiveMapping",
           "POLICY_OPTION_ROW", "SCENARIOS", "SCENARIO_ROWS", "Scenario", "ScenarioRow", "choices_help",
           "controller_names", "controllers_table", "policy_name", "policy_row", "register_controller",
           "register_scenario", "replace_steps", "scenario_names", "scenarios_table", "unregister",
           "with_row"]
