"""The statement of conformity: the decision rule of the unit model, each check with value, U,
limit and verdict, and a certificate that cannot contradict its run."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.limits import load_limits, verdict
from bench.run_state import Outcome
from db.repo.certificates import canonical_sha256
from station.certificates.certificate import certificate_content
from station.certificates.conformity import check_uncertainties, conformity_statement
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.pdf import certificate_lines, conformity_line, render_pdf
from tests.support.limits import SPEC

K = [[0.0201, 0.0201 * 0.004, 0.0], [0.0, 0.0199, -0.0199 * 0.004], [0.0, 0.0, 0.02]]
CAL = {
    "unit": "SN-C",
    "channel_unit": "V",
    "procedure": "static-12",
    "bias": [1.54, 1.46, 1.5],
    "bias_sigma": [1e-5, 2e-5, 3e-5],
    "scale_matrix": K,
    "scale_matrix_sigma": [[2e-6] * 3] * 3,
    "terms": ["bias", "scale_matrix"],
    "extra": {},
    "residual_rms": 7.7e-6,
    "g_check": {"after": {"mean_error_m_s2": 1e-4, "std_m_s2": 4e-4}},
}
FIT = FittedModel.from_contract(CAL)


def _limits(tmp_path: Path, rule: str | None) -> object:
    spec = {**SPEC, **({"decision_rule": rule} if rule else {})}
    p = tmp_path / "l.json"
    p.write_text(json.dumps({"format": "calbench-unit-limits/1", "models": {"M": spec}}))
    return load_limits(p)["M"]


def test_uncertainty_of_each_check_is_k_sigma_and_the_ratio_propagates_both_terms() -> None:
    us = check_uncertainties(FIT, None, 16)
    assert us["bias_y"] == pytest.approx(4.0e-5) and us["scale_x"] == pytest.approx(4.0e-6)
    assert us["g_error_after"] == pytest.approx(2 * 4e-4 / 4)  # s/sqrt(n), k = 2
    # the ratio K_xy/K_xx by Monte Carlo (a different formulation than the first-order propagation)
    rng = np.random.default_rng(1)
    kxx = rng.normal(K[0][0], 2e-6, 400_000)
    kxy = rng.normal(K[0][1], 2e-6, 400_000)
    assert us["cross_axis_xy"] == pytest.approx(2 * np.std(kxy / kxx), rel=0.02)


def test_guard_band_rejects_a_value_within_u_of_its_limit_that_simple_acceptance_passes(
    tmp_path: Path,
) -> None:
    us = check_uncertainties(FIT, None, 16)
    # bias_x = 1.54 is 0.01 V inside its limit 1.55: U = 2e-5 V leaves it acceptable either way
    simple = _limits(tmp_path, None)
    guarded = _limits(tmp_path, "guarded-acceptance")
    assert verdict(FIT, simple, us)[0] is Outcome.PASS
    assert verdict(FIT, guarded, us)[0] is Outcome.PASS
    # move bias_x to 1.549990: inside [1.45, 1.55] but within U = 2e-5 of 1.55
    near = FittedModel.from_contract({**CAL, "bias": [1.54999, 1.46, 1.5]})
    out_s, checks_s = verdict(near, simple, us)
    out_g, checks_g = verdict(near, guarded, us)
    assert out_s is Outcome.PASS and out_g is Outcome.FAIL
    bx = checks_g[0]
    assert bx.name == "bias_x" and not bx.passed
    assert bx.acceptance_high == pytest.approx(1.55 - 2e-5) and bx.acceptance_low == pytest.approx(
        1.45 + 2e-5
    )
    assert checks_s[0].acceptance_high == pytest.approx(1.55) and checks_s[0].expanded_uncertainty == 2e-5
    with pytest.raises(ValueError, match="guarded acceptance needs the expanded uncertainty"):
        verdict(near, guarded, None)


def test_unknown_decision_rule_is_refused_naming_the_model(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="model 'M': decision_rule must be one of"):
        _limits(tmp_path, "shared-risk")


def _content(checks: list[LimitCheck], outcome: str | None) -> dict[str, object]:
    inputs = CertificateInputs(
        run=RunFacts(id="r1", procedure="static-12"),
        unit=UnitFacts("S", model="M", channel_unit="V"),
        calibration=FIT,
        g_local_m_s2=9.81,
        limit_checks=tuple(checks),
        g_check_n=16,
        outcome=outcome,
        limits_model="M",
    )
    lab = Laboratory("Lab", "1 Road", "room", "A. Person")
    return certificate_content(inputs, lab, number="CB-1", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC))


def test_certificate_lists_every_check_and_states_the_runs_outcome(tmp_path: Path) -> None:
    outcome, checks = verdict(
        FIT, _limits(tmp_path, "guarded-acceptance"), check_uncertainties(FIT, None, 16)
    )
    # as the run stored them, read back as the service reads them
    rows = [LimitCheck.from_stored(json.loads(json.dumps(dataclasses.asdict(c))), "stored") for c in checks]
    assert rows == list(checks)
    c = _content(rows, outcome.value)
    conf = c["conformity"]
    assert isinstance(conf, dict) and conf["requested"] and conf["outcome"] == "PASS"
    assert "guarded acceptance (ILAC-G8:09/2019 4.2.2" in conf["decision_rule"]
    assert [r["quantity"] for r in conf["checks"]] == [ch.name for ch in checks] and len(conf["checks"]) == 13
    assert conf["checks"][0]["expanded_uncertainty"] == 2e-5 and conf["checks"][0]["verdict"] == "conforms"
    assert (
        c["g_check"]["after"]["expanded_uncertainty_m_s2"]
        == conf["checks"][-1]["expanded_uncertainty"]
        == 2e-4
    )
    line = conformity_line(c)
    assert line.startswith("Conformity: PASS against the limits of unit model M (guarded acceptance)")
    text = "\n".join(certificate_lines(c, "0" * 64, kind=FIT.kind))
    assert "7  Statement of conformity" in text and "Acceptance interval" in text
    # a run stored as FAIL cannot get a certificate that lists passing checks
    with pytest.raises(ValueError, match="disagrees with its limit checks"):
        _content(rows, "FAIL")


def test_without_limits_the_certificate_says_no_statement_is_made() -> None:
    c = _content([], None)
    conf = c["conformity"]
    assert isinstance(conf, dict) and not conf["requested"] and conf["checks"] == []
    assert conformity_line(c) == "Conformity: no statement of conformity (no specification limits apply)"
    assert conformity_statement([], None, "M", None)["decision_rule"] == "not applicable"


def test_datasheet_units_convert_the_fit_with_matching_digits() -> None:
    from station.certificates.datasheet_units import datasheet_results

    d = datasheet_results(FIT, None)
    s = d["sensitivity"]
    # K_xx = 0.0201 V/(m/s2) -> 0.0201 * 9.80665 * 1000 mV/g = 197.113665 mV/g; U = 4e-6 * 9806.65 = 0.039
    assert s["unit"] == "mV/g" and s["expanded_uncertainty"][0] == pytest.approx(0.039)
    assert s["value"][0] == pytest.approx(197.114, abs=1e-9)  # to U's last digit (0.001)
    x = d["cross_axis"]
    assert x["unit"] == "mrad" and x["value"][0][0] is None
    assert x["value"][0][1] == pytest.approx(4.00, abs=1e-9)  # K_xy/K_xx = 0.004 -> 4.00 mrad
    assert d["zero_g_output"]["value"][1] == pytest.approx(1460.00) and d["zero_g_output"]["unit"] == "mV"


@pytest.mark.skipif(
    shutil.which("pdftoppm") is None or shutil.which("pdftotext") is None,
    reason="poppler-utils not installed",
)
@pytest.mark.parametrize("with_limits", [True, False])
def test_every_pdf_page_renders_and_states_the_stored_outcome(tmp_path: Path, with_limits: bool) -> None:
    if with_limits:
        outcome, checks = verdict(FIT, _limits(tmp_path, None), check_uncertainties(FIT, None, 16))
        rows, stored = list(checks), outcome.value
        expected = "Conformity: PASS against the limits of unit model M (simple acceptance)"
    else:
        rows, stored = [], "PASS"
        expected = "Conformity: no statement of conformity (no specification limits apply)"
    c = _content(rows, stored)
    pdf = tmp_path / "c.pdf"
    pdf.write_bytes(render_pdf(c, canonical_sha256(c), kind=FIT.kind))
    subprocess.run(["pdftoppm", "-r", "50", "-png", str(pdf), str(tmp_path / "page")], check=True)
    pngs = sorted(tmp_path.glob("page-*.png"))
    assert len(pngs) >= 3
    for n, png in enumerate(pngs, start=1):
        data = png.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = struct.unpack(">II", data[16:24])
        assert (width, height) == (414, 585), (width, height)  # A4 at 50 dpi
        text = subprocess.run(
            ["pdftotext", "-f", str(n), "-l", str(n), "-layout", str(pdf), "-"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        assert " ".join(text.split()).count(expected) == 1, (n, text[:400])
        assert f"Page {n} of {len(pngs)}" in text


@pytest.mark.slow
def test_g_check_u_covers_the_after_mean_error_over_simulated_recordings() -> None:
    from bench.estimation.g_check import correct, g_check
    from bench.estimation.static_fit import fit_static
    from tests.support.static_sim import random_truth, tumble_specific_force

    rng = np.random.default_rng(3)
    f = tumble_specific_force()
    m, g = f.shape[0], float(np.linalg.norm(f[0]))
    z = []
    for _ in range(300):
        b, K = random_truth(rng)
        sigma = 2e-5
        y = b + f @ K.T + rng.normal(0.0, sigma, (m, 3))
        fit = fit_static(f, y, np.repeat((sigma**2 * np.eye(3))[None], m, axis=0))
        gc = g_check(correct(y, fit.bias, fit.K), g)
        z.append(gc.mean_error_m_s2 / (2 * gc.std_m_s2 / np.sqrt(m)))  # error / U
    # U never too small: the mean error after the fit stays well inside its U (conservative)
    assert np.max(np.abs(z)) < 0.5
