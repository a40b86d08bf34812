"""Nothing scored is never a figure: a 3σ (a spread) of fewer than two samples is not estimable
(NaN, shown as —), and a bench or campaign whose episodes would score less than a second after
their warm-up is refused in one line before any work.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dss14_env import cli
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
