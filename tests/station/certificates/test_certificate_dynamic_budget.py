"""The certificate of a moving-table (oscillation-2axis) fit carries a Type A + Type B budget."""

from __future__ import annotations

import datetime as dt
from typing import Any

import numpy as np
import pytest

from bench.calibration.analysis import Analysis, analyse
from bench.fitted_model import FittedModel
from bench.recording import Recording
from bench.uncertainty.budget import WANDER_GROUP
from station.certificates.budget import CertificateBudget, TypeBSettings, certificate_budget
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.rounding import round_expanded
from station.certificates.statements import DYNAMIC_COVERAGE_STATEMENT, RUN_MEAN_BIAS
from station.settings import Settings
from tests.support.dynamic_sim import oscillation

# the dynamic budget refits a moving recording once per Type B input
pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

ZERO = TypeBSettings(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def recorded() -> tuple[Analysis, dict[str, Any]]:
    _, rec = oscillation(seed=4)
    analysis = analyse(rec)
    return analysis, analysis.contract()


def _content(rec: Recording, cal: dict[str, Any], budget: CertificateBudget | None) -> dict[str, Any]:
    inputs = CertificateInputs(
        run=RunFacts(id="r2", procedure="oscillation-2axis",
                     started_at=dt.datetime(2025, 1, 1, tzinfo=dt.UTC),
                     finished_at=dt.datetime(2025, 1, 1, 0, 5, tzinfo=dt.UTC)),
        unit=UnitFacts("SN-DYN", channel_unit="V"), calibration=FittedModel.from_contract(cal),
        g_local_m_s2=rec.sidecar.g_local_m_s2, temp_c=(24.4, 24.6, 24.9), budget=budget,
        budget_note="" if budget else "no recording",
    )  # fmt: skip
    lab = Laboratory("Test lab", "1 Lab Road", "room 2", "A. Person")
    return certificate_content(
        inputs, lab, number="CB-2025-00012", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC)
    )


def test_dynamic_certificate_has_a_budget(recorded: tuple[Analysis, dict[str, Any]]) -> None:
    analysis, cal = recorded
    rec = analysis.recording
    typed = certificate_budget(analysis, FittedModel.from_contract(cal), TypeBSettings.of(Settings()))
    budget = typed.to_content()
    assert "refit" in budget["sensitivity_method"] and "sandwich" in budget["type_a"]
    groups = {i["group"] for i in budget["inputs"]}
    assert {"table angle", "local gravity", "DAQ gain", "DAQ offset"} <= groups
    assert any("table_tilt" in s for s in budget["not_evaluated"])  # the fit estimates the tilt
    b_x = budget["quantities"]["b_x"]
    lines = {c["name"]: c for c in b_x["contributions"]}
    assert lines["DAQ offset, channel x"]["sensitivity"] == pytest.approx(1.0, abs=1e-4)
    assert lines["DAQ gain, channel x"]["contribution"] == pytest.approx(1e-5 * abs(cal["bias"][0]), rel=2e-3)
    K_xx = budget["quantities"]["K_xx"]
    g_line = next(c for c in K_xx["contributions"] if c["name"] == "local gravity g_local")
    g = rec.sidecar.g_local_m_s2
    assert g_line["sensitivity"] == pytest.approx(-cal["scale_matrix"][0][0] / g, rel=0.03)
    c = _content(rec, cal, typed)
    assert c["uncertainty_statement"] == DYNAMIC_COVERAGE_STATEMENT
    u = np.array(c["results"]["bias"]["expanded_uncertainty"])
    np.testing.assert_allclose(
        u, [2 * budget["quantities"][n]["u_c"] for n in ("b_x", "b_y", "b_z")], rtol=0.03
    )
    assert np.all(u > 2 * np.array(cal["bias_sigma"]))  # the DAQ gain (1e-5 × 1.5 V) adds to Type A
    # the station's stated unit wander: a line per sensor axis, so the bias U is the long-run bias's
    assert WANDER_GROUP in groups and any(ln["group"] == WANDER_GROUP for ln in b_x["contributions"])
    assert RUN_MEAN_BIAS not in c["statements"]


def test_dynamic_budget_without_type_b_is_two_sigma(recorded: tuple[Analysis, dict[str, Any]]) -> None:
    analysis, cal = recorded
    rec = analysis.recording
    res = _content(rec, cal, certificate_budget(analysis, FittedModel.from_contract(cal), ZERO))["results"]
    assert res["bias"]["k"] == 2.0 and res["scale_matrix"]["k"] == 2.0
    # no stated wander: the fit's own bias sigma, and the certificate says which bias it is
    content = _content(rec, cal, certificate_budget(analysis, FittedModel.from_contract(cal), ZERO))
    assert (RUN_MEAN_BIAS in content["statements"]) == (cal["bias_reference"] == "run_mean")
    for name, sig in (("bias", "bias_sigma"), ("scale_matrix", "scale_matrix_sigma")):
        expected = [
            round_expanded(v, s)[1] for v, s in zip(np.ravel(cal[name]), np.ravel(cal[sig]), strict=True)
        ]
        assert np.ravel(res[name]["expanded_uncertainty"]).tolist() == expected
