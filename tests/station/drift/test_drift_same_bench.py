"""Drift test on the certificate's own bench: the bench-common Type B contributions of the
certificate's budget (DAQ gain and offset, table angle, levelling, local g) are the same in both
runs and cancel in the difference, so the limit is set by the Type A parts; a bias shift of
3.5 combined Type A σ is flagged, which the full U/k (≈ 2.5× wider for a V unit) hid."""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from api.simulated_recording import write_simulated
from bench.calibration import calibrate_recording
from bench.calibration.analysis import analyse
from bench.fitted_model import FittedModel
from bench.recording import read_recording
from bench.uncertainty.budget import TYPE_A_NAME
from db.models import Certificate
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth
from station.certificates.budget import TypeBSettings, certificate_budget
from station.certificates.certificate import certificate_content
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.drift import certificate_bench, compare
from station.settings import Settings

G = 9.81535


@pytest.fixture(scope="module")
def certified(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], FittedModel]:
    """(certificate content with the default bench's budget, the fit it states)."""
    truth = SensorTruth.typical("V", seed=4)
    physics = SensorPhysics(truth, DEFAULT_AXES, None, G, seed=5, encoder_resolution_deg=1e-4)
    path = tmp_path_factory.mktemp("drift") / "sim.csv"
    write_simulated(path, simulate_static(static12_poses_deg(), 5.0, physics, 100.0), serial="SN-D", seed=5)
    rec = read_recording(path)
    cal = calibrate_recording(rec).fitted_model()
    budget = certificate_budget(analyse(rec), cal, TypeBSettings.of(Settings()))
    inputs = CertificateInputs(
        run=RunFacts(id="r1", procedure="static-12", bench="bench-A"),
        unit=UnitFacts("SN-D", channel_unit="V"), calibration=cal, g_local_m_s2=G, budget=budget,
    )  # fmt: skip
    lab = Laboratory("Lab", "1 Road", "room", "A. Person")
    content = certificate_content(inputs, lab, number="CB-2025-00001", issued_at=dt.datetime(2025, 1, 2))
    return content, cal


def _type_a(content: dict[str, Any], name: str) -> float:
    lines = content["results"]["uncertainty_budget"]["quantities"][name]["contributions"]
    return float(next(c["contribution"] for c in lines if c["name"] == TYPE_A_NAME))


def test_bias_shift_of_three_and_a_half_type_a_sigma_is_flagged(
    certified: tuple[dict[str, Any], FittedModel],
) -> None:
    content, cal = certified
    u_a = _type_a(content, "b_x")
    u_check = float(cal.bias_sigma[0])
    u_full = content["results"]["bias"]["expanded_uncertainty"][0] / content["results"]["bias"]["k"]
    assert u_full > 2.0 * u_a  # the V unit's budget is dominated by the DAQ's gain and offset
    shift = 3.5 * math.hypot(u_a, u_check)
    bias = np.asarray(content["results"]["bias"]["value"]) + np.array([shift, 0.0, 0.0])
    check = replace(cal, bias=bias)

    same = compare(content, check, 3.0, same_bench=True)
    row = {r["name"]: r for r in same["coefficients"]}["bias[0]"]
    assert row["u_reference"] == pytest.approx(u_a, rel=0.01)  # Type A; temperature lines ≪ 1 %
    assert row["u_certificate"] == pytest.approx(u_full)
    assert row["limit"] == pytest.approx(3.0 * math.hypot(row["u_reference"], u_check))
    assert row["exceeded"] and same["flagged"]
    ref = same["reference_uncertainty"]
    assert ref["same_bench"] is True and "DAQ gain" in ref["bias"] and "cancel" in ref["bias"]

    other = compare(content, check, 3.0, same_bench=False)  # another bench: nothing cancels
    row = {r["name"]: r for r in other["coefficients"]}["bias[0]"]
    assert row["u_reference"] == pytest.approx(u_full)
    assert not row["exceeded"]


def test_scale_limits_drop_only_the_bench_common_lines(
    certified: tuple[dict[str, Any], FittedModel],
) -> None:
    content, cal = certified
    rows = {r["name"]: r for r in compare(content, cal, 3.0, same_bench=True)["coefficients"]}
    quantities = content["results"]["uncertainty_budget"]["quantities"]
    row, q = rows["scale_matrix[0,1]"], quantities["K_xy"]
    own = ("Type A", "temperature: bias", "temperature: scale")
    kept = [c["contribution"] for c in q["contributions"] if c["group"] in own]
    assert row["u_reference"] == pytest.approx(math.sqrt(sum(x**2 for x in kept)))
    assert _type_a(content, "K_xy") <= row["u_reference"] < q["u_c"]


def test_certificate_bench_from_content(certified: tuple[dict[str, Any], dict[str, Any]]) -> None:
    content, _ = certified
    cert = Certificate(run_id="r1", unit_id=1, year=2025, serial=1, number="CB-2025-00001",
                       content=content, sha256="0" * 64)  # fmt: skip
    assert certificate_bench(None, cert) == "bench-A"  # type: ignore[arg-type]
