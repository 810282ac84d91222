"""Statistics a certificate states to two significant digits print with both digits, the
trailing zero kept (GUM 7.2.6): a residual RMS of 2.0e-5 V is "2.0e-05", not the one-digit
"2e-05"; rounding is half-up on the decimal value, as for U (station.certificates.rounding)."""

from __future__ import annotations

import datetime as dt

import pytest

from bench.fitted_model import FittedModel
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.pdf import certificate_lines
from station.certificates.rounding import format_significant, round_significant


@pytest.mark.parametrize(
    ("x", "text"),
    [(2.0e-5, "2.0e-05"), (2.04e-5, "2.0e-05"), (0.1, "0.10"), (12.0, "12"), (9.96e-7, "1.0e-06"),
     (0.125, "0.13"), (-3.0e-4, "-0.00030"), (0.0, "0")],
)  # fmt: skip
def test_format_significant_keeps_both_digits(x: float, text: str) -> None:
    assert format_significant(x) == text


def test_round_significant_is_half_up_and_refuses_non_finite() -> None:
    assert round_significant(0.125) == 0.13 and round_significant(0.0125) == 0.013  # binary .2g: 0.12
    with pytest.raises(ValueError, match="significant"):
        round_significant(float("nan"))


def test_certificate_states_and_prints_two_digits() -> None:
    cal = {
        "unit": "SN-T", "channel_unit": "V", "procedure": "static-12", "terms": ["bias", "scale_matrix"],
        "bias": [1.5, 1.5, 1.5], "bias_sigma": [1e-5] * 3,
        "scale_matrix": [[0.0175, 0, 0], [0, 0.0175, 0], [0, 0, 0.0175]],
        "scale_matrix_sigma": [[1e-6] * 3] * 3,
        "residual_rms": 2.04e-5,
        "g_check": {"before": {"mean_error_m_s2": 0.125, "std_m_s2": 0.30},
                    "after": {"mean_error_m_s2": -1.0e-4, "std_m_s2": 3.04e-4}},
    }  # fmt: skip
    inputs = CertificateInputs(
        run=RunFacts(id="r1", procedure="static-12"), unit=UnitFacts("SN-T", channel_unit="V"),
        calibration=FittedModel.from_contract(cal), g_local_m_s2=9.81535,
    )  # fmt: skip
    lab = Laboratory("Lab", "1 Road", "room", "A. Person")
    c = certificate_content(inputs, lab, number="CB-2025-00003", issued_at=dt.datetime(2025, 1, 2))
    assert c["results"]["residual_rms"]["value"] == 2.0e-5
    before = c["g_check"]["before"]
    assert (before["mean_error_m_s2"], before["std_m_s2"]) == (0.13, 0.30)
    # no window count in the inputs: the check's U cannot be stated, and says so
    assert before["expanded_uncertainty_m_s2"] == "not stated" and before["n"] == "not stated"
    text = "\n".join(certificate_lines(c, "0" * 64, kind=inputs.calibration.kind))
    assert "Residual RMS of the fit: 2.0e-05 V." in text
    for cell in ("0.13", "0.30", "-0.00010", "0.00030"):
        assert cell in text.split(), cell
