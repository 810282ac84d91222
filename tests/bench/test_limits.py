"""Unit-model limits: the intervals from the file, the checks of a fit, malformed files named."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.limits import Limit, choose_limits, load_limits, verdict
from bench.run_state import Outcome
from tests.support.fits import stored_fit
from tests.support.limits import SPEC


def write(tmp_path: Path, models: object, fmt: str = "calbench-unit-limits/1") -> Path:
    p = tmp_path / "limits.json"
    p.write_text(json.dumps({"format": fmt, "models": models}))
    return p


def contract(
    bias: list[float], K: list[list[float]], g_err: float = 0.001, channel_unit: str = "V"
) -> FittedModel:
    return stored_fit(
        channel_unit=channel_unit,
        bias=bias,
        scale_matrix=K,
        g_check={"after": {"mean_error_m_s2": g_err, "std_m_s2": 0.001}},
    )


def test_a_fit_inside_every_interval_passes_and_each_excursion_is_named(tmp_path: Path) -> None:
    lim = load_limits(write(tmp_path, {"M": SPEC}))["M"]
    good_K = [[0.0201, 0.0201 * 0.004, 0.0], [0.0, 0.0199, -0.0199 * 0.004], [0.0, 0.0, 0.02]]
    outcome, checks = verdict(contract([1.54, 1.46, 1.5], good_K), lim)
    assert outcome is Outcome.PASS and len(checks) == 13 and all(c.passed for c in checks)
    bad_K = [[0.0203, 0.0203 * 0.006, 0.0], [0.0, 0.02, 0.0], [0.0, 0.0, 0.01979]]
    outcome, checks = verdict(contract([1.56, 1.5, 1.449], bad_K, g_err=-0.005), lim)
    assert outcome is Outcome.FAIL
    # bias 1.56 > 1.55 and 1.449 < 1.45; K_xx = 1.5 % high; K_zz 1.05 % low; K_xy/K_xx = 0.006
    assert [c.name for c in checks if not c.passed] == [
        "bias_x",
        "bias_z",
        "scale_x",
        "scale_z",
        "cross_axis_xy",
        "g_error_after",
    ]
    scale_x = next(c for c in checks if c.name == "scale_x")
    assert scale_x.low == pytest.approx(0.0198) and scale_x.high == pytest.approx(0.0202)
    assert scale_x.unit == "V/(m/s2)"


def test_no_limits_give_no_verdict_and_nan_never_passes() -> None:
    assert verdict(contract([0.0] * 3, [[1, 0, 0], [0, 1, 0], [0, 0, 1]]), None) == (None, ())
    assert not Limit("x", "V", -1.0, 1.0).check(math.nan).passed
    assert Limit("x", "V", None, 1.0).check(-1e9).passed


def test_the_shipped_file_loads_and_a_fit_in_other_units_is_refused() -> None:
    lim = load_limits()["ADXL325"]
    assert lim.channel_unit == "V"
    with pytest.raises(ValueError, match="for V outputs, the fit is in 'g'"):
        verdict(contract([0.0] * 3, [[1, 0, 0], [0, 1, 0], [0, 0, 1]], channel_unit="g"), lim)


@pytest.mark.parametrize(
    "models,fmt,what",
    [
        (
            {"M": {k: v for k, v in SPEC.items() if k != "bias_tolerance"}},
            None,
            "model 'M' lacks bias_tolerance",
        ),
        (
            {"M": {**SPEC, "scale_tolerance_rel": -0.01}},
            None,
            "scale_tolerance_rel must be a finite number > 0",
        ),
        ({"M": {**SPEC, "nominal_bias": [1.5, 1.5]}}, None, "nominal_bias must be 3 finite numbers"),
        ({"M": SPEC}, "other/1", "expected an object with format"),
    ],
)
def test_malformed_files_name_the_file_and_key(
    tmp_path: Path, models: object, fmt: str | None, what: str
) -> None:
    path = write(tmp_path, models, fmt or "calbench-unit-limits/1")
    with pytest.raises(ValueError, match=what) as info:
        load_limits(path)
    assert str(path) in str(info.value)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not JSON"):
        load_limits(path)
    with pytest.raises(ValueError, match="cannot read the limits file"):
        load_limits(tmp_path / "missing.json")


def test_a_stored_limit_check_is_read_back_and_a_bad_one_is_named() -> None:
    check = LimitCheck("bias_x", "V", 1.52, 1.45, 1.55, True, 2e-5, 1.45002, 1.54998, "guarded-acceptance")
    assert LimitCheck.from_stored(json.loads(json.dumps(dataclasses.asdict(check))), "run R") == check
    # stored before checks carried U: no U, the acceptance interval is the tolerance interval
    old = {
        "name": "scale_x",
        "unit": "V/(m/s2)",
        "value": 0.0201,
        "low": 0.0198,
        "high": None,
        "passed": True,
    }
    assert LimitCheck.from_stored(old, "run R") == LimitCheck(
        "scale_x", "V/(m/s2)", 0.0201, 0.0198, None, True, None, 0.0198, None, "simple-acceptance"
    )
    with pytest.raises(ValueError, match=r"^run R: limit check 3: key 'passed' is missing$"):
        LimitCheck.from_stored({k: v for k, v in old.items() if k != "passed"}, "run R: limit check 3")
    with pytest.raises(ValueError, match=r"^run R: key 'value' must be a number, got '0.02'$"):
        LimitCheck.from_stored({**old, "value": "0.02"}, "run R")
    with pytest.raises(ValueError, match=r"^run R: key 'name' is missing$"):
        LimitCheck.from_stored({k: v for k, v in old.items() if k != "name"}, "run R")
    with pytest.raises(ValueError, match=r"^run R: must be an object, got list$"):
        LimitCheck.from_stored([], "run R")


def test_a_model_is_judged_only_by_its_own_limits_and_each_refusal_says_why(tmp_path: Path) -> None:
    table = load_limits(write(tmp_path, {"M": SPEC, "N": {**SPEC, "channel_unit": "count"}}))
    assert choose_limits(table, "M", "V", "N").limits is table["M"]
    # a model the file lacks is never judged by the default model's limits
    other = choose_limits(table, "M-335", "V", "M")
    assert other.limits is None
    assert other.reason == "no limits are configured for model M-335" and other.known_models == ("M", "N")
    # the default judges only a unit that names no model
    assert choose_limits(table, None, "V", "M").limits is table["M"]
    assert choose_limits(table, "  ", None, "M").limits is table["M"]
    none = choose_limits(table, None, "V", "")
    assert none.limits is None and "names no model and no default limits model is set" in none.reason
    gone = choose_limits(table, None, "V", "X")
    assert gone.limits is None and "default limits model X is not in the limits file" in gone.reason
    # limits for other outputs do not apply; an unknown output unit is not held against them
    wrong = choose_limits(table, "N", "V")
    assert wrong.limits is None
    assert wrong.reason == "the limits of model N are for count outputs, the unit's outputs are in V"
    assert choose_limits(table, "N", None).limits is table["N"]
