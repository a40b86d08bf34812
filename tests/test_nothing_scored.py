"""Nothing scored is never a figure: a 3σ (a spread) of fewer than two samples is not estimable
(NaN, shown as —), and a bench or campaign whose episodes would score less than a second after
their warm-up is refused in one line before any work.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dss14_env import cli
from dss14_env.bench.bench import unscored_controllers
from dss14_env.core.results import ErrorStats


def test_the_spread_of_one_sample_is_not_estimable() -> None:
    one = ErrorStats.of([2.5])
    assert math.isnan(one.three_sigma) and one.rms == 2.5 and one.max == 2.5 and one.mean == 2.5
    assert all(math.isnan(v) for v in ErrorStats.of([]).to_dict().values())
    assert ErrorStats.of([1.0, -1.0]).three_sigma == 3.0


@pytest.mark.parametrize("argv", [
    ["campaign", "--plants", "1", "--controllers", "pi_kp1", "--steps", "251"],
    ["bench", "--controllers", "pi_kp1", "--scenarios", "hold_front", "--no-sweep", "--steps", "251"],
])
def test_a_run_that_would_score_one_sample_is_refused(tmp_path: Path, capsys, argv) -> None:
    out = tmp_path / "out"
    assert cli.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--steps: 251" in err and "warm-up" in err, err
    assert not out.exists()


def test_a_bench_whose_controller_scores_nothing_is_an_error(tmp_path: Path, capsys, monkeypatch) -> None:
    """Every episode's 3σ not estimable (as for a policy that terminates every episode): the
    results are written, and the command says that nothing was scored instead of exiting 0.
    """
    monkeypatch.setattr(ErrorStats, "of", classmethod(lambda cls, x: cls(*[math.nan] * 4)))
    out = tmp_path / "out"
    assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "--scenarios", "hold_front",
                     "--no-sweep", "--episodes", "2", "--no-figures", "--no-progress",
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pi_kp1: scored nothing in any scenario" in err, err
    assert (out / "results.json").is_file()


def test_a_scoring_controller_is_not_unscored() -> None:
    cell = {"servo_error_mdeg": {"az": {"three_sigma": {"value": math.nan}},
                                 "el": {"three_sigma": {"value": 0.5}}}}
    none = {"servo_error_mdeg": {"az": {"three_sigma": {"value": None}},
                                 "el": {"three_sigma": {"value": math.nan}}}}
    results = {"summary": {"a": {"s1": none, "s2": cell}, "b": {"s1": none}}}
    assert unscored_controllers(results) == ["b"]
