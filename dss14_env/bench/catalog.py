"""The one catalog of the bench: a row per controller and a row per scenario.

Every list of controllers or scenarios in the package derives from here: the runner's names,
the bench's defaults, budgets and loaded axes, the figures' groups, the ``dss14 bench`` /
``dss14 campaign`` help and choices, the campaign's controller set and the tables of
docs/bench.md.  No name is special: the MPC is a row that runs one episode at a time, the
PPO policies are rows with a ``policy``.

**Add a controller** (two files): its module (a
:class:`~dss14_env.baselines.base.Controller` whose constructor takes the environment) and
its row in :data:`CONTROLLER_ROWS`.  **Add a scenario** (two files): its environment preset in
:data:`dss14_env.envs.presets.PRESETS` and its row in :data:`SCENARIO_ROWS` (episode length and
the default and ``--quick`` budgets).  docs/bench.md shows a worked example of each.

>>> CONTROLLERS["mpc"].batchable, CONTROLLERS["ppo"].policy
(False, 'residual_pi')
>>> SCENARIOS["hold_side"].loaded_axes, SCENARIOS["step"].group
(('az',), 'move')
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from dss14_env.envs.presets import PRESETS


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
    _policy_row("ppo_general", "ppo_general", "general plain PPO, one policy for every scenario: "
                "the policy sets the command about the commanded rate fed forward, no controller "
                "underneath; trained on a mixture of tracks, holds, steps and slews "
                "(`agents/policies/ppo_general`, docs/rl.md)"),
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
)

#: the row that ``--ppo-model`` replaces by the given policy
POLICY_OPTION_ROW = "ppo"


def _by_name(rows: tuple[Any, ...]) -> Mapping[str, Any]:
    return MappingProxyType({r.name: r for r in rows})


#: controller rows by name
CONTROLLERS: Mapping[str, ControllerRow] = _by_name(CONTROLLER_ROWS)


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
    """

    env: Mapping[str, Any]
    steps: int
    warmup_s: float = 0.0
    description: str = ""


@dataclass(frozen=True)
class ScenarioRow:
    """One scenario of the bench.

    :param name: its name in options, tables and results (and its preset's,
        :data:`dss14_env.envs.presets.PRESETS`: environment keys, warm-up, loaded axes)
    :param default: the default run's budget (long and many enough for the statistics)
    :param quick: the ``--quick`` budget (the CI smoke test)
    :param steps: episode length of :func:`dss14_env.bench.runner.run` without ``steps``,
        control periods (None: the preset's ``max_episode_steps``)
    :param group: ``"wind"`` (disturbance rejection) or ``"move"`` (commanded moves): the
        axes of errors_3sigma.png
    :param traced: the bench keeps the first seed's time histories (the figures draw them)
    :param sweep: the error-vs-wind sweep's direction this scenario anchors (``"front"``,
        ``"side"``; None: no sweep)
    :param bench: in a bench run without ``--scenarios``
    :param preset: the preset it runs, when not the one of its name (a variant of a preset)
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
    preset: str | None = None
    env: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    note: str = ""

    @property
    def preset_name(self) -> str:
        """The name of the preset it runs."""
        return self.preset or self.name

    @property
    def description(self) -> str:
        """The preset's description, with the variant's note."""
        d = PRESETS[self.preset_name].description
        return f"{d}; {self.note}" if self.note else d

    @property
    def loaded_axes(self) -> tuple[str, ...]:
        """The axes the scenario's wind loads (its preset's)."""
        return PRESETS[self.preset_name].loaded_axes

    def scenario(self) -> Scenario:
        """The runner's scenario: the preset's keys (and the variant's), warm-up and description."""
        p = PRESETS[self.preset_name]
        return Scenario({**p.kwargs, **self.env}, self.steps or p.max_episode_steps, p.warmup_s,
                        self.description)


#: the scenarios, in table order; hold budgets: a 95 % half-width <= 5 % of the loaded axis'
#: 3σ for the batched controllers (60-s episodes scatter about 15 % (1 σ) from seed to seed, so
#: 128 of them give about 2-3 %); the MPC gets what fits the 5-minute budget
SCENARIO_ROWS: tuple[ScenarioRow, ...] = (
    ScenarioRow("hold_front", Budget(60.0, 128, 8), Budget(15.0, 8, 1), traced=True, sweep="front"),
    ScenarioRow("hold_side", Budget(60.0, 128, 8), Budget(15.0, 8, 1), traced=True, sweep="side"),
    # no wind: episodes differ only in start and quantisation
    ScenarioRow("step", Budget(20.0, 16, 2), Budget(15.0, 4, 1), steps=1000, group="move", traced=True),
    # random 30-70 km/h wind and direction: wide by design
    ScenarioRow("track", Budget(40.0, 128, 4), Budget(10.0, 8, 1)),
    # the commanded move dominates
    ScenarioRow("slew", Budget(50.0, 32, 2), Budget(10.0, 4, 1), steps=2500, group="move"),
    # the report's encoders close to the axes: the batched controllers only (the MPCs' budget is
    # the drive-encoder holds')
    ScenarioRow("hold_front_axis", Budget(60.0, 64, 0), Budget(15.0, 4, 0), preset="hold_front",
                env={"encoders": "axis"}, note="axis encoders (the structure's angles at the axes)"),
    ScenarioRow("hold_side_axis", Budget(60.0, 64, 0), Budget(15.0, 4, 0), preset="hold_side",
                env={"encoders": "axis"}, note="axis encoders (the structure's angles at the axes)"),
)

#: scenario rows by name
SCENARIOS: Mapping[str, ScenarioRow] = _by_name(SCENARIO_ROWS)


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
    return tuple(r.name for r in CONTROLLER_ROWS if which is None or getattr(r, which))


def scenario_names(which: str | None = None) -> tuple[str, ...]:
    """Scenario names: all, or those of a bench run without ``--scenarios`` (``"bench"``)."""
    return tuple(r.name for r in SCENARIO_ROWS if which is None or getattr(r, which))


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
    for r in CONTROLLER_ROWS:
        runs = "batched" if r.batchable else "one episode at a time"
        lines.append(f"| `{r.name}` | {r.description} | {runs} | {_yes(r.bench)} / {_yes(r.campaign)} |")
    return "\n".join(lines) + "\n"


def scenarios_table() -> str:
    """The markdown table of the scenario rows (docs/bench.md): what each runs by default
    (batched episodes, one-at-a-time episodes) and with ``--quick``.
    """
    lines = ["| name | what | episode | batched episodes | one-at-a-time episodes | `--quick` |",
             "|---|---|---|---|---|---|"]
    for r in SCENARIO_ROWS:
        p, d, q = PRESETS[r.preset_name], r.default, r.quick
        warm = f", {p.warmup_s:g} s warm-up" if p.warmup_s else ""
        lines.append(f"| `{r.name}` | {r.description} | {d.seconds:g} s{warm} | {d.episodes} | "
                     f"{d.sequential} | {q.seconds:g} s x {q.episodes} ({q.sequential}) |")
    return "\n".join(lines) + "\n"


def replace_steps(sc: Scenario, steps: int) -> Scenario:
    """``sc`` with another episode length."""
    return dataclasses.replace(sc, steps=int(steps))


__all__ = ["Budget", "CONTROLLERS", "CONTROLLER_ROWS", "ControllerRow", "POLICY_OPTION_ROW",
           "SCENARIOS", "SCENARIO_ROWS", "Scenario", "ScenarioRow", "choices_help",
           "controller_names", "controllers_table", "policy_name", "policy_row", "replace_steps",
           "scenario_names", "scenarios_table", "with_row"]
