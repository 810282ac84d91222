"""``[table.limits]`` of the bench file: the table's own rates, accelerations, travel and settling
reach the preview (a move timed by hand on them), a file without the section keeps the documented
defaults, and every absurd, non-finite or ill-shaped value is refused naming the file and key."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.bench_config import BenchConfigError, load_bench_config
from bench.procedures import DEFAULT_TABLE_LIMITS, preview
from bench.procedures.steps import Dwell, MoveTo, Procedure
from tests.bench.test_bench_config import REAL, write

LIMITS = """
[table.limits]
max_rate_deg_s = [10.0, 40.0]
max_acc_deg_s2 = [5.0, 100.0]
continuous = [true, false]
travel_deg = [[-180, 180], [-95, 95]]
settle_s = 1.5
"""
# REAL is a two-axis table (azimuth, tilt); the section goes after its axes, before [gravity]
WITH_LIMITS = REAL.replace("[gravity]", LIMITS + "[gravity]", 1)


def test_the_file_s_limits_time_a_move_as_worked_out_by_hand(tmp_path: Path) -> None:
    limits = load_bench_config(write(tmp_path, WITH_LIMITS)).table_limits()
    assert limits.max_rate_deg_s == (10.0, 40.0) and limits.continuous == (True, False)
    assert (limits.pos_lo_deg[1], limits.pos_hi_deg[1], limits.settle_s) == (-95.0, 95.0, 1.5)
    # azimuth 0 -> 90 deg at 10 deg/s, 5 deg/s^2: v^2/a = 20 < 90, trapezoid 90/10 + 10/5 = 11 s;
    # tilt 0 -> 30 deg at 40 deg/s, 100 deg/s^2: v^2/a = 16 < 30, 30/40 + 40/100 = 1.15 s
    proc = Procedure("p", (MoveTo((90.0, 30.0), "a", settle_s=1.5), Dwell("a", 4.0)), {}, n_axes=2)
    pv = preview(proc, limits)
    assert pv.ok, pv.problems
    assert pv.duration_s == pytest.approx(11.0 + 1.5 + 4.0, abs=1e-12)


def test_moves_beyond_the_file_s_travel_or_settling_are_problems(tmp_path: Path) -> None:
    limits = load_bench_config(write(tmp_path, WITH_LIMITS)).table_limits()
    proc = Procedure("p", (MoveTo((0.0, 120.0), "far", settle_s=0.5), Dwell("far", 1.0)), {}, n_axes=2)
    problems = preview(proc, limits).problems
    assert any("axis 2 angle 120 deg outside [-95, 95] deg" in p for p in problems), problems
    assert any("settling 0.5 s is shorter than the table's 1.5 s" in p for p in problems), problems


def test_a_file_without_limits_runs_with_the_documented_defaults(tmp_path: Path) -> None:
    c = load_bench_config(write(tmp_path, REAL))
    assert c.limits is None and c.table_limits() == DEFAULT_TABLE_LIMITS


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ("max_rate_deg_s = [10.0, 40.0]", "max_rate_deg_s = [10.0, 0.0]", "max_rate_deg_s[1]", "(0, 36000]"),
        ("max_rate_deg_s = [10.0, 40.0]", "max_rate_deg_s = [10.0, nan]", "max_rate_deg_s[1]", "finite"),
        ("max_rate_deg_s = [10.0, 40.0]", "max_rate_deg_s = [inf, 40.0]", "max_rate_deg_s[0]", "finite"),
        ("max_rate_deg_s = [10.0, 40.0]", "max_rate_deg_s = [1e9, 40.0]", "max_rate_deg_s[0]", "(0, 36000]"),
        (
            "max_rate_deg_s = [10.0, 40.0]",
            "max_rate_deg_s = [10.0]",
            "max_rate_deg_s",
            "one value per axis (2",
        ),
        ("max_rate_deg_s = [10.0, 40.0]", "", "max_rate_deg_s", "missing"),
        (
            "max_acc_deg_s2 = [5.0, 100.0]",
            "max_acc_deg_s2 = [-5.0, 100.0]",
            "max_acc_deg_s2[0]",
            "(0, 1e+06]",
        ),
        ("max_acc_deg_s2 = [5.0, 100.0]", 'max_acc_deg_s2 = [5.0, "fast"]', "max_acc_deg_s2[1]", "finite"),
        ("continuous = [true, false]", "continuous = [true, 0]", "continuous[1]", "true or false"),
        (
            "travel_deg = [[-180, 180], [-95, 95]]",
            "travel_deg = [[-180, 180], [95, -95]]",
            "travel_deg[1]",
            "below",
        ),
        (
            "travel_deg = [[-180, 180], [-95, 95]]",
            "travel_deg = [[-180, 180], [-95]]",
            "travel_deg[1]",
            "[lowest",
        ),
        (
            "travel_deg = [[-180, 180], [-95, 95]]",
            "travel_deg = [[-200, 180], [-95, 95]]",
            "travel_deg[0]",
            "[-180, 180]",
        ),
        ("settle_s = 1.5", "settle_s = -1", "settle_s", "[0, 600]"),
        ("settle_s = 1.5", "settle_s = nan", "settle_s", "finite"),
        ("settle_s = 1.5", "settling_s = 1.5", "settling_s", "unknown key"),
    ],
)
def test_each_bad_limit_is_refused_naming_file_and_key(
    tmp_path: Path, old: str, new: str, key: str, words: str
) -> None:
    assert old in WITH_LIMITS
    path = write(tmp_path, WITH_LIMITS.replace(old, new, 1))
    with pytest.raises(BenchConfigError) as info:
        load_bench_config(path)
    assert info.value.key == f"table.limits.{key}", str(info.value)
    assert str(path) in str(info.value) and words in str(info.value), str(info.value)


def test_limits_that_are_not_a_table_are_refused(tmp_path: Path) -> None:
    path = write(tmp_path, REAL.replace('url = "socket://', 'limits = 3\nurl = "socket://', 1))
    with pytest.raises(BenchConfigError, match=r"table\.limits: must be a table"):
        load_bench_config(path)
