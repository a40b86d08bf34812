"""The wind direction and speed grid (dss14_env/bench/grid.py, scripts/direction_grid.py): its
points, its scenarios, its options, a small run through the bench's runner and its table, and
the committed results."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from dss14_env.bench import grid as G
from dss14_env.core.results import POINTING_AXES

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "docs" / "results" / "direction_grid.json"


def test_the_grid_covers_every_direction_and_the_light_and_strong_wind() -> None:
    pts = {(d, v) for _, d, v in G.grid_points()}
    assert {(d, 50.0) for d in (0.0, 45.0, 90.0, 135.0, 180.0)} <= pts
    assert {(d, v) for d in (0.0, 90.0) for v in (10.0, 70.0)} <= pts
    names = [n for n, _, _ in G.grid_points()]
    assert len(set(names)) == len(names)


def test_a_grid_point_is_the_hold_with_its_wind() -> None:
    sc = G.grid_scenario(135.0, 70.0, 30.0)
    assert sc.env["scenario"] == "hold" and sc.env["wind_speed_kmh"] == 70.0
    assert sc.env["wind_direction"] == pytest.approx(3 * math.pi / 4)
    assert sc.steps == 1500 and sc.group == "wind"


@pytest.mark.parametrize("episodes,seconds,option", [(1, 30.0, "--episodes"), (8, 5.5, "--seconds")])
def test_bad_options_are_named(episodes: int, seconds: float, option: str) -> None:
    with pytest.raises(ValueError, match=option):
        G.run_grid(["pi_kp1"], episodes, seconds)


def test_bad_controllers_and_policies_are_named(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--controllers: unknown controller 'nope'"):
        G.grid_controllers(["nope"])
    with pytest.raises(ValueError, match="--ppo-model"):
        G.grid_controllers(None, str(tmp_path / "missing.zip"))


#: the points of the small run (the front and side of the 50-km/h row)
SMALL_POINTS = [("hold_0deg_50kmh", 0.0, 50.0), ("hold_90deg_50kmh", 90.0, 50.0)]


@pytest.fixture(scope="module")
def small() -> dict:
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(G, "grid_points", lambda: SMALL_POINTS)
        return G.run_grid(["pi_kp1", "lqg_pointing"], episodes=3, seconds=7.0)


def test_every_point_has_both_beam_axes_and_the_paired_ratio(small: dict) -> None:
    assert set(small["summary"]["pi_kp1"]) == {n for n, _, _ in SMALL_POINTS}
    for name in small["points"]:
        for ax in POINTING_AXES:
            c = small["summary"]["lqg_pointing"][name]["pointing_error_mdeg"][ax]
            assert c["n_episodes"] == 3 and c["ci95"][0] <= c["value"] <= c["ci95"][1]
            r = small["summary"]["lqg_pointing"][name]["vs_reference_pointing_error_mdeg"][ax]
            pi = small["summary"]["pi_kp1"][name]["pointing_error_mdeg"][ax]["value"]
            assert r["value"] == pytest.approx(c["value"] / pi, rel=1e-9)


def test_the_wind_loads_the_axis_it_blows_on(small: dict) -> None:
    """Front wind loads elevation, side wind cross-elevation (the PI's pointing 3σ)."""
    s = small["summary"]["pi_kp1"]
    front, side = s["hold_0deg_50kmh"]["pointing_error_mdeg"], s["hold_90deg_50kmh"]["pointing_error_mdeg"]
    assert front["el"]["value"] > 3 * front["xel"]["value"]
    assert side["xel"]["value"] > 1.5 * side["el"]["value"]


def test_the_table_has_a_row_per_point_and_controller(small: dict) -> None:
    t = G.grid_table(small)
    assert t.count("| 50 km/h from 90° |") == 2 and "el ÷ pi_kp1" in t and "Wall time" in t


def test_the_script_names_a_missing_policy_before_any_work(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "direction_grid.py"), "--ppo-model",
                           str(tmp_path / "none"), "--out-json", str(tmp_path / "g.json"),
                           "--out-md", str(tmp_path / "g.md")], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.startswith("direction_grid: --ppo-model")
    assert not (tmp_path / "g.json").exists()


def test_the_committed_grid_and_its_table_agree() -> None:
    results = json.loads(COMMITTED.read_text())
    assert results["meta"]["controllers"] == list(G.CONTROLLERS)
    assert results["grid"]["episodes"] == G.EPISODES and results["grid"]["seconds"] == G.SECONDS
    assert set(results["points"]) == {n for n, _, _ in G.grid_points()}
    md = (COMMITTED.with_suffix(".md")).read_text()
    assert G.grid_table(results) in md
