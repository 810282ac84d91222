"""Certificate rounding (GUM 7.2.6), content and PDF, without a bench."""

from __future__ import annotations

import datetime as dt
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from bench.calibration import calibrate_recording
from bench.diagnosis.stored import StoredDiagnosis, StoredFinding
from bench.fitted_model import ContractError, FittedModel
from bench.recording import read_recording
from db.repo.certificates import canonical_sha256
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.pdf import certificate_lines, render_pdf
from station.certificates.rounding import expanded_quantity, round_expanded
from station.certificates.statements import NOT_REPRODUCED, ONLY_ITEM, REQUIRED_ITEMS, RUN_MEAN_BIAS
from tests.conftest import STATIC_EXAMPLE, copy_example


@pytest.mark.parametrize(
    ("value", "sigma", "expected"),
    [
        (1.504234567, 1.2345e-5, (1.504235, 2.5e-5)),  # U = 2.469e-5 -> 2.5e-5, value to 1e-6
        (0.0177312, 4.98e-7, (0.0177312, 1.0e-6)),  # U = 9.96e-7 rounds up to 1.0e-6
        (9.81, 0.00625, (9.81, 0.013)),  # 0.0125 half-up -> 0.013
        (-3.14159, 0.05, (-3.14, 0.10)),
        (123456.0, 2400.0, (123500.0, 4800.0)),  # U = 4800: value to the hundreds
    ],
)
def test_expanded_uncertainty_has_two_significant_digits(
    value: float, sigma: float, expected: tuple[float, float]
) -> None:
    v, u = round_expanded(value, sigma)
    assert v == pytest.approx(expected[0], abs=1e-15) and u == pytest.approx(expected[1], rel=1e-12)


def test_rounding_refuses_non_finite_and_negative() -> None:
    for bad in ((float("nan"), 1.0), (1.0, float("inf")), (1.0, -1.0)):
        with pytest.raises(ValueError, match="cannot round"):
            round_expanded(*bad)
    with pytest.raises(ValueError, match="shape"):
        expanded_quantity([1.0, 2.0], [0.1], "V")


CAL = {
    "unit": "SN-C",
    "channel_unit": "V",
    "procedure": "static-12",
    "bias": [1.5042, 1.5003, 1.4955],
    "bias_sigma": [1.1e-5, 1.2e-5, 0.9e-5],
    "scale_matrix": [[0.01744, 9.2e-5, -1.08e-4], [1e-5, 0.0175, 2e-5], [3e-5, -2e-5, 0.0176]],
    "scale_matrix_sigma": [[1.6e-6] * 3] * 3,
    "terms": ["bias", "scale_matrix"],
    "extra": {},
    "residual_rms": 7.7e-6,
    "g_check": {"after": {"mean_error_m_s2": 3.2e-9, "std_m_s2": 3.3e-4}},
}
FIT = FittedModel.from_contract(CAL)


def _content(fit: FittedModel = FIT) -> dict[str, object]:
    inputs = CertificateInputs(
        run=RunFacts(
            id="r1",
            procedure="static-12",
            started_at=dt.datetime(2025, 1, 1, tzinfo=dt.UTC),
            finished_at=dt.datetime(2025, 1, 1, 0, 5, tzinfo=dt.UTC),
            parameters={"dwell_s": 8.0},
        ),
        unit=UnitFacts("SN-C", model="ADXL325", channel_unit="V"),
        calibration=fit,
        g_local_m_s2=9.81535,
        temp_c=(24.4, 24.6, 24.9),
        diagnosis=StoredDiagnosis(
            (
                StoredFinding(
                    effect="nonlinearity_quadratic",
                    summary="z: k2 = 1.5e-3 per g",
                    parameters={"k2_per_g": [0, 0, 0.0015]},
                    sigma={},
                    delta_bic=-120.0,
                    residual_rms_after=None,
                ),
            )
        ),
    )
    lab = Laboratory("Test lab", "1 Lab Road", "room 2", "A. Person")
    return certificate_content(
        inputs, lab, number="CB-2025-00007", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC)
    )


def test_content_carries_the_17025_items_and_the_model_under_the_contract_names() -> None:
    c = _content()
    assert c["number"] == "CB-2025-00007" and c["end"] == "End of certificate"
    res = c["results"]
    assert res["bias"]["value"] == [1.5042, 1.5003, 1.4955]
    assert res["bias"]["expanded_uncertainty"] == [2.2e-5, 2.4e-5, 1.8e-5]
    assert res["scale_matrix"]["expanded_uncertainty"][0] == [3.2e-6] * 3
    assert c["g_check"]["before"].startswith("not stated") and c["g_check"]["after"]["std_m_s2"] == 3.3e-4
    assert c["diagnosis"]["findings"][0]["effect"] == "nonlinearity_quadratic"
    assert c["conditions"]["sensor_temperature"]["mean_c"] == 24.6
    assert "k = 2" in c["uncertainty_statement"]
    canonical_sha256(c)  # JSON-able without NaN


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils not installed")
def test_pdf_text_holds_number_results_and_hash(tmp_path: Path) -> None:
    c = _content()
    digest = canonical_sha256(c)
    path = tmp_path / "c.pdf"
    path.write_bytes(render_pdf(c, digest, kind=FIT.kind))
    text = subprocess.run(
        ["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True, check=True
    ).stdout
    for needle in (
        "Calibration Certificate",
        "CB-2025-00007",
        "Page 1 of 3",
        "Page 3 of 3",
        digest,
        "End of certificate",
        "nonlinearity_quadratic",
        "Customer address",
        "not stated",
        "Authorised by",
        "A. Person",
        "2025-01-01 00:00:00 UTC to 2025-01-01 00:05:00 UTC",
        "U, k = 2 (V)",
    ):
        assert needle in text, needle
    # bias and its U on one table row, to U's second significant digit (U = 2.2e-5 V: 6 decimals)
    assert re.search(r"x\s+1\.504200\s+0\.000022", text), text
    assert re.search(r"0\.0174400 ± 0\.0000032", text)


@pytest.mark.parametrize(
    ("method", "procedure", "over"),
    [
        (None, "oscillation-2axis", "over the static positions"),
        ("dynamic-batch", "static-12", "over 1 s blocks of the moving recording"),
    ],
)
def test_the_g_check_states_over_what_the_fits_kind_took_it(
    method: str | None, procedure: str, over: str
) -> None:
    """The |g| check's basis is the fit's own kind (its ``method``), whatever the run's
    procedure is called."""
    fit = FittedModel.from_contract({**CAL, "method": method})
    c = _content(fit)
    c["method"]["procedure"] = procedure
    heading = [ln for ln in certificate_lines(c, "0" * 64, kind=fit.kind) if ln.startswith("|g| check")]
    assert len(heading) == 1 and over in heading[0]


def test_every_17025_item_is_filled_and_missing_ones_say_not_stated() -> None:
    c = _content()
    missing = [clause for clause, path in REQUIRED_ITEMS.items() if _blank(_at(c, path))]
    assert missing == []
    not_given = {"name": "not stated", "address": "not stated", "source": "not given to the laboratory"}
    assert c["customer"] == not_given
    assert c["dates"]["received"] == "not stated" and c["item"]["model"] == "ADXL325"
    lab = Laboratory("L", "A", "room", "P", default_customer_name="Dept. 7", default_customer_address="B 2")
    inputs = CertificateInputs(
        run=RunFacts(procedure="static-12"),
        unit=UnitFacts("S", customer_name="Acme", received_on=dt.date(2025, 1, 1)),
        calibration=FIT,
        g_local_m_s2=None,
    )
    c2 = certificate_content(inputs, lab, number="N", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC))
    assert c2["customer"] == {"name": "Acme", "address": "not stated", "source": "unit registration"}
    assert c2["dates"]["received"] == "2025-01-01" and c2["conditions"]["g_local_m_s2"] == "not stated"
    inputs3 = CertificateInputs(run=RunFacts(), unit=UnitFacts("S"), calibration=FIT, g_local_m_s2=9.8)
    c3 = certificate_content(inputs3, lab, number="N", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC))
    assert c3["customer"]["name"] == "Dept. 7" and c3["customer"]["source"] == "laboratory default"


def _at(content: dict[str, object], path: str) -> object:
    value: object = content
    for key in path.split("."):
        assert isinstance(value, dict) and key in value, path
        value = value[key]
    return value


def _blank(value: object) -> bool:
    return value is None or value == "" or value == [] or value == {}


def test_a_run_mean_bias_u_is_said_to_be_the_runs_mean(tmp_path: Path) -> None:
    """A 12-window static fit keeps the independent-window model (no wander can be shown), so its
    bias sigma is the run's mean bias's: the contract says so and the certificate states it."""
    contract = calibrate_recording(read_recording(copy_example(STATIC_EXAMPLE, tmp_path))).to_contract()
    assert contract["bias_reference"] == "run_mean"
    statements = _content(FittedModel.from_contract(contract))["statements"]
    assert statements == [ONLY_ITEM, RUN_MEAN_BIAS, NOT_REPRODUCED]
    long_run = FittedModel.from_contract({**contract, "bias_reference": "long_run"})
    assert _content(long_run)["statements"] == [ONLY_ITEM, NOT_REPRODUCED]
    assert _content()["statements"] == [ONLY_ITEM, NOT_REPRODUCED]  # a fit stored without the key


def test_an_unknown_bias_reference_is_refused_by_name() -> None:
    with pytest.raises(ContractError, match="bias_reference"):
        FittedModel.from_contract({**CAL, "bias_reference": "mean"})
