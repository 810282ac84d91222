"""The typed fit parsed from a stored ``calibrate --json`` object: the same values as the fit that
produced it, and a renamed, missing or ill-typed key named in the error."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from api.simulated_recording import write_simulated
from bench.calibration import CalibrationResult, calibrate_recording
from bench.fit_kind import FitKind
from bench.fitted_model import DYNAMIC_BATCH, ContractError, FittedModel, GCheckSummary, NominalReference
from bench.recording import read_recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

G = 9.81535


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> CalibrationResult:
    physics = SensorPhysics(SensorTruth.typical("m/s2", seed=2), DEFAULT_AXES, None, G, seed=3)
    path = tmp_path_factory.mktemp("fitted") / "sim.csv"
    write_simulated(path, simulate_static(static12_poses_deg(), 2.0, physics, 100.0), serial="SN-F", seed=3)
    return calibrate_recording(read_recording(path))


def _stored(result: CalibrationResult) -> dict[str, Any]:
    """The contract as it comes back from a JSON column."""
    out: dict[str, Any] = json.loads(json.dumps(result.to_contract()))
    return out


def test_a_stored_fit_parses_to_the_values_of_the_fit_that_wrote_it(fitted: CalibrationResult) -> None:
    stored = _stored(fitted)
    parsed = FittedModel.from_contract(stored, "run R-1: stored fit")
    direct = fitted.fitted_model()
    for name in ("bias", "bias_sigma", "K", "K_sigma"):
        np.testing.assert_array_equal(getattr(parsed, name), getattr(direct, name))
    assert parsed.bias.tolist() == stored["bias"] and parsed.K.tolist() == stored["scale_matrix"]
    assert (parsed.unit_serial, parsed.channel_unit, parsed.procedure) == ("SN-F", "m/s2", "static-12")
    assert parsed.terms == ("bias", "scale_matrix") == direct.terms
    assert parsed.residual_rms == stored["residual_rms"] == direct.residual_rms
    assert parsed.g_after == GCheckSummary(
        stored["g_check"]["after"]["mean_error_m_s2"], stored["g_check"]["after"]["std_m_s2"]
    )
    assert parsed.g_after == direct.g_after and parsed.g_before == direct.g_before
    assert parsed.g_before is not None  # m/s2 output: the raw output is its own nominal
    assert (parsed.extra, parsed.method, parsed.kind) == ({}, None, FitKind.STATIC)


def test_the_nominal_of_a_before_check_and_a_dynamic_method_are_read() -> None:
    stored = {
        "unit": "",
        "channel_unit": "V",
        "procedure": "rate-1axis",
        "bias": [1, 2, 3],
        "bias_sigma": [0.1, 0.2, 0.3],
        "scale_matrix": [[1, 0, 0], [0, 2, 0], [0, 0, 3]],
        "scale_matrix_sigma": [[0.5] * 3] * 3,
        "terms": ["bias", "scale_matrix", "lever_arm"],
        "extra": {"lever_arm": {"r_m": [0.1, 0.0, 0.0]}},
        "residual_rms": None,
        "method": "dynamic-batch",
        "g_check": {
            "after": {"mean_error_m_s2": 0.0, "std_m_s2": 0.25},
            "before": {
                "mean_error_m_s2": -2,
                "std_m_s2": 1,
                "nominal": {"scale": 0.02, "bias": 0, "source": "s"},
            },
        },
    }
    fit = FittedModel.from_contract(stored)
    assert fit.g_before == GCheckSummary(-2.0, 1.0, NominalReference(0.02, 0.0, "s"))
    assert fit.residual_rms is None and fit.method == DYNAMIC_BATCH and fit.kind is FitKind.MOVING
    assert fit.extra == {"lever_arm": {"r_m": [0.1, 0.0, 0.0]}} and fit.K[2, 2] == 3.0
    # written back (a nominal |g| check added to a stored fit) in the stored form it was read from
    assert fit.g_before is not None
    assert fit.g_before.to_contract() == {
        "mean_error_m_s2": -2.0,
        "std_m_s2": 1.0,
        "nominal": {"scale": 0.02, "bias": 0.0, "source": "s"},
    }
    assert fit.g_after.to_contract() == stored["g_check"]["after"]


def _without(obj: dict[str, Any], path: str) -> dict[str, Any]:
    out = copy.deepcopy(obj)
    *head, last = path.split(".")
    node = out
    for key in head:
        node = node[key]
    del node[last]
    return out


@pytest.mark.parametrize(
    "path",
    [
        "bias",
        "scale_matrix_sigma",
        "channel_unit",
        "terms",
        "g_check",
        "g_check.after",
        "g_check.after.std_m_s2",
    ],
)
def test_a_missing_key_is_named_with_its_path(fitted: CalibrationResult, path: str) -> None:
    with pytest.raises(ContractError, match=rf"^run R-9: stored fit: key '{path}' is missing$"):
        FittedModel.from_contract(_without(_stored(fitted), path), "run R-9: stored fit")


def test_a_renamed_key_is_named(fitted: CalibrationResult) -> None:
    stored = _stored(fitted)
    stored["scale"] = stored.pop("scale_matrix")
    after = stored["g_check"]["after"]
    with pytest.raises(ValueError, match="key 'scale_matrix' is missing"):
        FittedModel.from_contract(stored)
    stored["scale_matrix"] = stored.pop("scale")
    after["mean_error"] = after.pop("mean_error_m_s2")
    with pytest.raises(ValueError, match=r"calibration: key 'g_check\.after\.mean_error_m_s2' is missing"):
        FittedModel.from_contract(stored)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("bias", [1.0, 2.0], "key 'bias' must be 3 numbers"),
        ("bias", [1.0, True, 2.0], "key 'bias' must be 3 numbers"),
        ("scale_matrix", [[1.0, 0.0, 0.0]] * 2, "key 'scale_matrix' must be 3 x 3 numbers"),
        ("scale_matrix_sigma", [[1.0, 0.0, "0"]] * 3, "key 'scale_matrix_sigma' must be 3 x 3 numbers"),
        ("unit", 7, "key 'unit' must be a string"),
        ("terms", "bias", "key 'terms' must be a list of strings"),
        ("residual_rms", "small", "key 'residual_rms' must be a number"),
        ("extra", [], "key 'extra' must be an object"),
        ("g_check", {"after": []}, "key 'g_check.after' must be an object"),
        (
            "g_check",
            {"after": {"mean_error_m_s2": "0", "std_m_s2": 1}},
            "g_check.after.mean_error_m_s2' must be a number",
        ),
    ],
)
def test_an_ill_typed_key_is_named(fitted: CalibrationResult, key: str, value: object, message: str) -> None:
    stored = _stored(fitted)
    stored[key] = value
    with pytest.raises(ContractError, match=message):
        FittedModel.from_contract(stored)


def test_a_fit_that_is_not_an_object_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ContractError, match=r"^stored: the fit must be an object, got list"):
        FittedModel.from_contract([1, 2], "stored")
