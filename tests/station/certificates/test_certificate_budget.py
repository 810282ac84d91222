"""The certificate's uncertainty budget on a simulated recording: Type A only gives U = k u_A, the
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
from scipy.stats import t as student_t

from api.simulated_recording import to_recording, write_simulated
from bench.calibration import calibrate_recording
from bench.calibration.analysis import StaticDesign, analyse, budget_design
from bench.estimation.static_fit import fit_static
from bench.fitted_model import FittedModel
from bench.recording import Recording, read_recording
from benchmarks.study_sigmas_static import poses, truth_for
from db.repo.certificates import canonical_sha256
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth
from station.certificates.budget import CertificateBudget, TypeBSettings, certificate_budget
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.pdf import render_pdf
from station.certificates.results import bias_statements
from station.certificates.rounding import round_expanded
from station.certificates.statements import RUN_MEAN_BIAS
from station.settings import Settings

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


def _content(cal: dict[str, Any], budget: CertificateBudget | None) -> dict[str, Any]:
    inputs = CertificateInputs(
        run=RunFacts(id="r1", procedure="static-12", started_at=dt.datetime(2025, 1, 1, tzinfo=dt.UTC),
                     finished_at=dt.datetime(2025, 1, 1, 0, 5, tzinfo=dt.UTC)),
        unit=UnitFacts("SN-B", channel_unit="V"), calibration=FittedModel.from_contract(cal),
        g_local_m_s2=G, temp_c=(24.4, 24.6, 24.9), budget=budget,
        budget_note="" if budget else "no recording",
    )  # fmt: skip
    lab = Laboratory("Test lab", "1 Lab Road", "room 2", "A. Person")
    return certificate_content(
        inputs, lab, number="CB-2025-00011", issued_at=dt.datetime(2025, 1, 2, tzinfo=dt.UTC)
    )


def test_type_b_zero_gives_k_type_a_to_two_digits(recorded: tuple[Recording, dict[str, Any]]) -> None:
    """With no Type B input U is k u_A, k = t_95.45 %(ν) of the Type A line's own degrees of
    freedom (EA-4/02 table, ``coverage_factor``), the largest k of the group for the group; u_A is
    the fit's estimator under the excess estimated without bias (``bench.uncertainty.type_a``), a
    second estimate of the variance the fit's σ states with its clipped, inflated excess: the two
    agree within the scatter of a variance estimated from 24 residual degrees of freedom."""
    rec, cal = recorded
    budget = certificate_budget(analyse(rec), FittedModel.from_contract(cal), ZERO)
    res = _content(cal, budget)["results"]
    qs = budget.budget.quantities
    assert all(len(q.contributions) == 1 or max(c.contribution for c in q.contributions[1:]) == 0 for q in qs)
    for q in qs:
        nu = q.contributions[0].dof
        assert 1 <= nu < math.inf and q.nu_eff == pytest.approx(nu)
        assert q.k == pytest.approx(float(student_t.ppf(0.97725, math.floor(nu))), rel=1e-9)
    u_a = np.array([q.contributions[0].contribution for q in qs])
    sigma = np.concatenate([np.ravel(cal["bias_sigma"]), np.ravel(cal["scale_matrix_sigma"])])
    assert np.all((u_a > 0.5 * sigma) & (u_a < 1.5 * sigma)), (u_a / sigma).round(2)
    values = np.concatenate([np.ravel(cal["bias"]), np.ravel(cal["scale_matrix"])])
    for name, sl in (("bias", slice(0, 3)), ("scale_matrix", slice(3, 12))):
        k = max(round(q.k, 3) for q in qs[sl])
        assert res[name]["k"] == k > 2.0
        expected = [round_expanded(v, s, k)[1] for v, s in zip(values[sl], u_a[sl], strict=True)]
        assert np.ravel(res[name]["expanded_uncertainty"]).tolist() == expected
    assert budget.to_content()["quantities"]["K_yy"]["nu_eff"] == pytest.approx(qs[7].nu_eff, rel=1e-3)


def test_default_type_b_inputs_raise_u_as_the_budget_says(recorded: tuple[Recording, dict[str, Any]]) -> None:
    rec, cal = recorded
    tb = TypeBSettings.of(Settings())
    assert tb.table_angle_u_deg == 0.001 and tb.g_local_u_m_s2 == 1e-5 and tb.daq_gain_u_rel == 1e-5
    budget = certificate_budget(analyse(rec), FittedModel.from_contract(cal), tb)
    names = {i.group for i in budget.budget.inputs}
    assert {"table angle", "base levelling x", "local gravity", "DAQ gain", "DAQ offset",
            "temperature: bias", "temperature: scale"} <= names  # fmt: skip
    stated = budget.to_content()
    b_x = stated["quantities"]["b_x"]
    gain_x = next(c for c in b_x["contributions"] if c["name"] == "DAQ gain, channel x")
    assert gain_x["contribution"] == pytest.approx(abs(cal["bias"][0]) * 1e-5, rel=2e-3)  # ∂b/∂ε = b
    K_xx = stated["quantities"]["K_xx"]
    g_line = next(c for c in K_xx["contributions"] if c["name"] == "local gravity g_local")
    assert g_line["contribution"] == pytest.approx(cal["scale_matrix"][0][0] / G * 1e-5, rel=2e-3)
    root_sum = math.sqrt(sum(c["contribution"] ** 2 for c in b_x["contributions"]))
    assert b_x["u_c"] == pytest.approx(root_sum, rel=5e-3)  # lines carry 3 digits
    res = _content(cal, budget)["results"]
    u = np.array(res["bias"]["expanded_uncertainty"])
    np.testing.assert_allclose(
        u, [2 * stated["quantities"][n]["u_c"] for n in ("b_x", "b_y", "b_z")], rtol=0.03
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
    budget = certificate_budget(
        analyse(bare),
        FittedModel.from_contract({**cal, "channel_unit": "count"}),
        TypeBSettings.of(Settings()),
    )
    notes = " ".join(budget.not_evaluated)
    assert "digital" in notes and "temperature" in notes
    assert not any(i.group == "DAQ gain" for i in budget.budget.inputs)
    assert budget.to_content()["not_evaluated"] == list(budget.not_evaluated)


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils not installed")
def test_pdf_shows_the_budget_tables(recorded: tuple[Recording, dict[str, Any]], tmp_path: Path) -> None:
    rec, cal = recorded
    c = _content(
        cal, certificate_budget(analyse(rec), FittedModel.from_contract(cal), TypeBSettings.of(Settings()))
    )
    path = tmp_path / "c.pdf"
    path.write_bytes(render_pdf(c, canonical_sha256(c), kind=FittedModel.from_contract(cal).kind))
    text = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True,
                          check=True).stdout  # fmt: skip
    for needle in ("Uncertainty budget", "Bias b: contributions", "Scale factors K_ii", "DAQ gain",
                   "local gravity", "combined standard uncertainty u_c", "coverage factor k",
                   "Welch–Satterthwaite", "K_yy"):  # fmt: skip
        assert needle in text, needle


def test_combined_reads_u_c_and_the_largest_stated_k_of_each_quantity() -> None:
    from bench.estimation.static_design import PARAMETER_NAMES
    from bench.uncertainty.budget import Budget, QuantityBudget

    # u_c of parameter i is (i + 1)·1e-6; k of K_yz is 2.12349 (stated 2.123), the largest of K
    ks = {"b_y": 2.0004, "K_yz": 2.12349, "K_xx": 2.05}
    quantities = tuple(
        QuantityBudget(n, 0.0, (), (i + 1) * 1e-6, 50.0, ks.get(n, 2.0), 0.0)
        for i, n in enumerate(PARAMETER_NAMES)
    )
    typed = CertificateBudget(Budget(quantities, (), np.zeros((0, 12)), "analytic"), "V", ("none",))
    u_b, k_b = typed.combined("bias")
    np.testing.assert_array_equal(u_b, [1e-6, 2e-6, 3e-6])
    assert k_b == 2.0
    u_K, k_K = typed.combined("scale_matrix")
    np.testing.assert_array_equal(u_K, np.arange(4, 13).reshape(3, 3) * 1e-6)
    assert k_K == 2.123
    stated = typed.to_content()["quantities"]
    assert (stated["K_yz"]["k"], stated["K_yz"]["u_c"], stated["K_yz"]["unit"]) == (2.123, 9e-6, "V/(m/s2)")
    with pytest.raises(ValueError, match="budget quantity 'K': expected 'bias' or 'scale_matrix'"):
        typed.combined("K")


def test_type_a_line_counts_each_type_b_input_once(recorded: tuple[Recording, dict[str, Any]]) -> None:
    """With inputs stated far larger than the scatter the windows show (this simulated bench has no
    such errors), their expected share takes the between-window excess out and below zero: the
    Type A lines fall below the lines without inputs (those already at the floor stay), no lower
    than the floor, half the variance
    of the fit's estimator under the windows' own noise (itself at least the within-window-only
    fit's σ, the smallest any weighting reaches); the certificate names the excess model and the
    components below zero."""
    rec, cal = recorded
    analysis = analyse(rec)
    stored = FittedModel.from_contract(cal)

    def type_a(tb: TypeBSettings) -> tuple[np.ndarray, str]:
        b = certificate_budget(analysis, stored, tb)
        return np.array([q.contributions[0].contribution for q in b.budget.quantities]), b.type_a_basis

    line0, basis = type_a(ZERO)
    assert "taken out" in basis
    design = budget_design(analysis)
    assert isinstance(design, StaticDesign) and not design.correlated_windows
    noise_only = fit_static(design.f_m_s2, design.y_mean, design.window_cov, between_window=False).sigma
    large = TypeBSettings(0.5, 1e-2, 1e-5, 1e-5, 1e-5, 0.5, 1e-2)
    line, basis = type_a(large)
    assert np.all(line <= line0 * (1 + 1e-9)) and np.sum(line < line0 * 0.999) >= 6, line / line0
    assert np.all(line >= math.sqrt(0.5) * noise_only * (1 - 1e-9)), line / noise_only
    assert "estimated below zero" in basis and "excess model" in basis


def _wander_r(span_s: float, tc_s: float) -> float:
    """r(T) by the double integral (1/T²) ∫∫ exp(−|t − t'| / T_c) dt dt' on a fine grid."""
    t = (np.arange(4000) + 0.5) * span_s / 4000
    return math.sqrt(float(np.mean(np.exp(-np.abs(t[:, None] - t[None, :]) / tc_s))))


def test_a_stated_wander_adds_its_run_mean_line_to_the_static_bias_and_leaves_k_alone(
    recorded: tuple[Recording, dict[str, Any]],
) -> None:
    """Independent window errors: the fit's bias sigma is already the run mean's (a shift common
    to the windows is b), so the Type A line stays and the unit's wander averaged over the
    windows' span is added per sensor axis, |K_ij| r(T) σ_w; K's budget is the same as without
    the wander, and the certificate no longer says its bias U is the run's mean."""
    rec, cal = recorded
    analysis, stored = analyse(rec), FittedModel.from_contract(cal)
    level, tc = 3.9e-4, 200.0
    plain = certificate_budget(analysis, stored, ZERO)
    stated = certificate_budget(analysis, stored, dataclasses.replace(ZERO, bias_wander_m_s2=level))
    span = max(w.end_s for w in analysis.fit.windows) - min(w.start_s for w in analysis.fit.windows)
    r = _wander_r(span, tc)
    K = np.array(cal["scale_matrix"])
    for i, (q0, q) in enumerate(zip(plain.budget.quantities[:3], stated.budget.quantities[:3], strict=True)):
        lines = [c for c in q.contributions if c.group == "bias wander over the run"]
        assert [c.channel for c in lines] == [0, 1, 2]
        np.testing.assert_allclose([c.contribution for c in lines], np.abs(K[i]) * r * level, rtol=1e-6)
        assert q.contributions[0].contribution == pytest.approx(q0.contributions[0].contribution, rel=1e-12)
        assert q.u_c**2 == pytest.approx(q0.u_c**2 + sum(c.contribution**2 for c in lines), rel=1e-12)
    for q0, q in zip(plain.budget.quantities[3:], stated.budget.quantities[3:], strict=True):
        assert (q.u_c, q.k) == pytest.approx((q0.u_c, q0.k), rel=1e-12)
    assert "long-run bias" in stated.type_a_basis and "long-run" not in plain.type_a_basis
    assert stored.bias_reference == "run_mean"
    assert bias_statements(stored, plain) == [RUN_MEAN_BIAS] and bias_statements(stored, stated) == []


def test_a_fit_with_the_shared_wander_states_its_bias_against_the_run_mean_beside_the_stated_wander() -> None:
    """A 12.7-minute static-12 run whose temperature drift the fit takes as a wander shared by the
    windows (``bias_reference = "long_run"``): with a stated wander the bias's Type A line is the
    fit's sigma against the run's mean (its own wander's mean over the windows out, below the
    fit's sigma), the stated wander's lines are added, K's budget is unchanged."""
    tr = truth_for("temperature", 0, 0.0)
    run = simulate_static(poses("bench"), 55.0, SensorPhysics(tr, DEFAULT_AXES, seed=2000), 100.0)
    analysis = analyse(to_recording(run, serial="SN-W"))
    stored = analysis.fitted_model()
    design = budget_design(analysis)
    assert isinstance(design, StaticDesign) and design.correlated_windows
    plain = certificate_budget(analysis, stored, ZERO)
    stated = certificate_budget(analysis, stored, dataclasses.replace(ZERO, bias_wander_m_s2=3.9e-4))
    line = np.array([q.contributions[0].contribution for q in stated.budget.quantities[:3]])
    np.testing.assert_allclose(line, design.bias_sigma_run_mean, rtol=1e-12)
    assert np.all(line < 0.5 * np.asarray(stored.bias_sigma)), line / np.asarray(stored.bias_sigma)
    assert all(
        sum(c.group == "bias wander over the run" for c in q.contributions) == 3
        for q in stated.budget.quantities[:3]
    )
    for q0, q in zip(plain.budget.quantities[3:], stated.budget.quantities[3:], strict=True):
        assert (q.u_c, q.k) == pytest.approx((q0.u_c, q0.k), rel=1e-12)
    assert "run's mean" in stated.budget.quantities[0].contributions[0].name
