"""The certificate's uncertainty budget on a simulated recording: Type A only gives U = 2σ, the
default Type B inputs raise U by the budget's rule, and the budget is in the JSON and the PDF."""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from api.certificates.budget import TypeBSettings, certificate_budget
from api.certificates.certificate import CertificateInputs, Laboratory, certificate_content
from api.certificates.pdf import render_pdf
from api.certificates.rounding import round_expanded
from api.settings import Settings
from api.simulated_recording import write_simulated
from bench.calibration import calibrate_recording
from bench.recording import Recording, read_recording
from db.repo.certificates import canonical_sha256
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

G = 9.81535
ZERO = TypeBSettings(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Recording, dict[str, Any]]:
    truth = SensorTruth.typical("V", seed=4)
    physics = SensorPhysics(truth, DEFAULT_AXES, None, G, seed=5, encoder_resolution_deg=1e-4)
    path = tmp_path_factory.mktemp("budget") / "sim.csv"
    write_simulated(path, simulate_static(static12_poses_deg(), 5.0, physics, 100.0), serial="SN-B", seed=5)
    rec = read_recording(path)
    return rec, calibrate_recording(rec).to_contract()


def _content(cal: dict[str, Any], budget: dict[str, Any] | None) -> dict[str, Any]:
    inputs = CertificateInputs(
        run={"id": "r1", "procedure": "static-12", "started_at": dt.datetime(2025, 1, 1, tzinfo=dt.UTC),
             "finished_at": dt.datetime(2025, 1, 1, 0, 5, tzinfo=dt.UTC), "parameters": {}},
        unit={"serial": "SN-B", "channel_unit": "V"}, calibration=cal, g_local_m_s2=G,
        temp_c=(24.4, 24.6, 24.9), budget=budget, budget_note="" if budget else "no recording",
    )  # fmt: skip
    lab = Laboratory("Test lab", "1 Lab Road", "room 2", "A. Person")
    return certificate_content(
        inputs, lab, number="CB-2025-00011", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC)
    )


def test_type_b_zero_gives_two_sigma_to_two_digits(recorded: tuple[Recording, dict[str, Any]]) -> None:
    rec, cal = recorded
    budget = certificate_budget(rec, cal, ZERO)
    res = _content(cal, budget)["results"]
    assert res["bias"]["k"] == 2.0 and res["scale_matrix"]["k"] == 2.0
    for name, sig in (("bias", "bias_sigma"), ("scale_matrix", "scale_matrix_sigma")):
        expected = [
            round_expanded(v, s)[1] for v, s in zip(np.ravel(cal[name]), np.ravel(cal[sig]), strict=True)
        ]
        assert np.ravel(res[name]["expanded_uncertainty"]).tolist() == expected
    assert budget["quantities"]["K_yy"]["nu_eff"] == "infinite"


def test_default_type_b_inputs_raise_u_as_the_budget_says(recorded: tuple[Recording, dict[str, Any]]) -> None:
    rec, cal = recorded
    tb = TypeBSettings.of(Settings())
    assert tb.table_angle_u_deg == 0.001 and tb.g_local_u_m_s2 == 1e-5 and tb.daq_gain_u_rel == 1e-5
    budget = certificate_budget(rec, cal, tb)
    names = {i["group"] for i in budget["inputs"]}
    assert {"table angle", "base levelling x", "local gravity", "DAQ gain", "DAQ offset",
            "temperature: bias", "temperature: scale"} <= names  # fmt: skip
    b_x = budget["quantities"]["b_x"]
    gain_x = next(c for c in b_x["contributions"] if c["name"] == "DAQ gain, channel x")
    assert gain_x["contribution"] == pytest.approx(abs(cal["bias"][0]) * 1e-5, rel=2e-3)  # ∂b/∂ε = b
    K_xx = budget["quantities"]["K_xx"]
    g_line = next(c for c in K_xx["contributions"] if c["name"] == "local gravity g_local")
    assert g_line["contribution"] == pytest.approx(cal["scale_matrix"][0][0] / G * 1e-5, rel=2e-3)
    root_sum = math.sqrt(sum(c["contribution"] ** 2 for c in b_x["contributions"]))
    assert b_x["u_c"] == pytest.approx(root_sum, rel=5e-3)  # lines carry 3 digits
    res = _content(cal, budget)["results"]
    u = np.array(res["bias"]["expanded_uncertainty"])
    np.testing.assert_allclose(
        u, [2 * budget["quantities"][n]["u_c"] for n in ("b_x", "b_y", "b_z")], rtol=0.03
    )
    assert np.all(u >= 2 * np.array(cal["bias_sigma"]) * 0.95)


def test_without_a_budget_the_statement_says_type_a_only(recorded: tuple[Recording, dict[str, Any]]) -> None:
    _, cal = recorded
    c = _content(cal, None)
    assert c["results"]["uncertainty_budget"] == "not stated"
    assert "Type A only" in c["uncertainty_statement"] and "no recording" in c["uncertainty_statement"]


def test_digital_output_and_no_table_are_listed_as_not_evaluated(
    recorded: tuple[Recording, dict[str, Any]],
) -> None:
    rec, cal = recorded
    bare = dataclasses.replace(rec, temp_c=None)
    budget = certificate_budget(bare, {**cal, "channel_unit": "count"}, TypeBSettings.of(Settings()))
    notes = " ".join(budget["not_evaluated"])
    assert "digital" in notes and "temperature" in notes
    assert not any(i["group"] == "DAQ gain" for i in budget["inputs"])


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils not installed")
def test_pdf_shows_the_budget_tables(recorded: tuple[Recording, dict[str, Any]], tmp_path: Path) -> None:
    rec, cal = recorded
    c = _content(cal, certificate_budget(rec, cal, TypeBSettings.of(Settings())))
    path = tmp_path / "c.pdf"
    path.write_bytes(render_pdf(c, canonical_sha256(c)))
    text = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True,
                          check=True).stdout  # fmt: skip
    for needle in ("Uncertainty budget", "Bias b: contributions", "Scale factors K_ii", "DAQ gain",
                   "local gravity", "combined standard uncertainty u_c", "coverage factor k",
                   "Welch–Satterthwaite", "K_yy"):  # fmt: skip
        assert needle in text, needle
