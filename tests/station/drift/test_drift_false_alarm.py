"""The drift test's false-alarm rate on an unchanged unit, by Monte Carlo.

Pairs of static-12 runs of one simulated unit (same truth, independent noise) are compared
as certificate and check. The stated ``false_alarm_probability`` must hold: the fraction of
flagged pairs stays within binomial scatter of it, and the normalised differences
Δ / sqrt(u_cert² + u_check² + u_rep²) have unit spread. The unit's bias wanders (Gauss-Markov,
std B, correlation time T_c), so each run's bias differs from the next by the run means of the
wander: var = 2 B² g(T/T_c), g(x) = 2 (x − 1 + e^(−x)) / x², the variance of a stationary
Gauss-Markov process's mean over T (Papoulis), which neither fit's σ can contain.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from api.simulated_recording import nominal_geometry, to_recording
from bench.calibration import calibrate_recording
from bench.fitted_model import FittedModel
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics
from drivers.sim.sensor_truth import SensorTruth
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.drift import compare
from tests.support.fits import stored_fit

RATE_HZ = 50.0
DWELL_S = 8.0
N_PAIRS = 100
LAB = Laboratory("Lab", "1 Road", "room", "A. Person")


def _fit(truth: SensorTruth, seed: int) -> tuple[FittedModel, float]:
    physics = SensorPhysics(
        truth, DEFAULT_AXES, None, 9.81535, seed=seed, sample_rate_hz=RATE_HZ, encoder_resolution_deg=1e-4
    )
    run = simulate_static(static12_poses_deg(), DWELL_S, physics, RATE_HZ)
    rec = to_recording(run, serial="SN-DRIFT-MC", geometry=nominal_geometry(run, (0.0, 0.0, 0.0)))
    span_s = run.segments[-1][1] - run.segments[0][0]
    return calibrate_recording(rec).fitted_model(), span_s


def _certificate(cal: FittedModel) -> dict[str, object]:
    inputs = CertificateInputs(
        run=RunFacts(id="r", procedure="static-12"),
        unit=UnitFacts("SN-DRIFT-MC", channel_unit="V"),
        calibration=cal,
        g_local_m_s2=9.81535,
    )
    return certificate_content(
        inputs, LAB, number="CB-2025-00001", issued_at=dt.datetime(2025, 1, 1, tzinfo=dt.UTC)
    )


@pytest.mark.slow
def test_unchanged_unit_is_flagged_at_the_stated_rate() -> None:
    truth = SensorTruth.typical("V", seed=4)
    B, tc = truth.noise.bias_instability_m_s2, truth.noise.bias_instability_tau_s
    assert B > 0  # the typical unit's bias wanders: the case the repeatability term is for
    flagged, z_rep, z_bias_without = 0, [], []
    p_stated = 0.0
    for i in range(N_PAIRS):
        ref, span_s = _fit(truth, 1000 + 2 * i)
        chk, _ = _fit(truth, 1001 + 2 * i)
        x = span_s / tc
        rep_m_s2 = B * math.sqrt(2.0 * 2.0 * (x - 1.0 + math.exp(-x)) / x**2)
        rep = np.abs(np.diag(chk.K)) * rep_m_s2
        out = compare(_certificate(ref), chk, 3.0, bias_repeatability=rep)
        flagged += bool(out["flagged"])
        p_stated = out["false_alarm_probability"]
        for r in out["coefficients"]:
            z_rep.append(r["delta"] / (r["limit"] / 3.0))
            if r["name"].startswith("bias"):
                z_bias_without.append(r["delta"] / math.hypot(r["u_reference"], r["u_check"]))
    rate = flagged / N_PAIRS
    assert rate <= p_stated + 3.0 * math.sqrt(p_stated * (1 - p_stated) / N_PAIRS), (rate, p_stated)
    assert 0.8 < float(np.std(z_rep)) < 1.2
    # without the repeatability term the biases' normalised differences are far too wide:
    # an unchanged unit would be flagged several times more often than stated
    assert float(np.std(z_bias_without)) > 1.3


def test_repeatability_widens_only_the_bias_limits() -> None:
    u = {"value": [1.0, 1.0, 1.0], "expanded_uncertainty": [2e-5] * 3, "unit": "V", "k": 2.0}
    m = {
        "value": np.eye(3).tolist(),
        "expanded_uncertainty": np.full((3, 3), 2e-6).tolist(),
        "unit": "V",
        "k": 2.0,
    }
    cert = {"results": {"bias": u, "scale_matrix": m}}
    check = stored_fit(
        bias=[1.0, 1.0, 1.0],
        bias_sigma=[1e-5] * 3,
        scale_matrix=np.eye(3).tolist(),
        scale_matrix_sigma=np.full((3, 3), 1e-6).tolist(),
    )
    rows = {r["name"]: r for r in compare(cert, check, 3.0, bias_repeatability=[2e-5, 0, 0])["coefficients"]}
    assert rows["bias[0]"]["limit"] == pytest.approx(3 * math.sqrt(1e-10 + 1e-10 + 4e-10))
    assert rows["bias[1]"]["limit"] == pytest.approx(3 * math.sqrt(2e-10))
    assert rows["scale_matrix[0,0]"]["limit"] == pytest.approx(3 * math.sqrt(2e-12))
    with pytest.raises(ValueError, match="repeatability"):
        compare(cert, check, 3.0, bias_repeatability=[1.0, float("nan"), 0.0])
