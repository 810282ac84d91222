"""``calbench diagnose`` on the real data sets of tests/data/real (docs/diagnose.md, "Real data
sets").

- imucal annotated session (counts, hand-held, six labelled poses): the window means disagree
  with their labels far beyond anything the windows' own samples allow for bias wander, so
  the finding is ``pose_error`` (the unit was not where its labels say), largest in the two
  z poses, where the first-order fit leaves ~17 counts on y.
- imucal Ferraris session (m/s², six labelled poses): nothing the data can support.
- IMU-TK Xsens (no labels, no table): orientation-free; ``pose_error`` has nothing to be off from.

Also the slow-noise cap (``bench.diagnosis.wander_cap``) against its two closed-form limits.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from api.cli import main
from bench.calibration.diagnose import diagnose_recording, recording_evidence
from bench.diagnosis.effects import first_order_design
from bench.diagnosis.wander_cap import half_difference_factor
from bench.recording import read_recording


@pytest.fixture(scope="module")
def real(real_dir: Path) -> Path:
    return real_dir


def _convert(tmp_path: Path, args: list[str]) -> Path:
    out = tmp_path / "rec.csv"
    assert main(["convert", *args, "-o", str(out)]) == 0
    return out


def test_half_difference_factor_limits() -> None:
    """g(h, T) -> 4h/(3T) (random walk of diffusion 2τ²/T) for h << T, -> 4T/h (white) for h >> T."""
    assert half_difference_factor(np.array(1e-3), 1.0) == pytest.approx(4e-3 / 3, rel=1e-3)
    assert half_difference_factor(np.array(1e4), 1.0) == pytest.approx(4e-4, rel=1e-3)


def test_half_difference_factor_against_a_simulated_gauss_markov_process() -> None:
    rng = np.random.default_rng(7)
    T, dt, n, reps = 2.0, 0.01, 100, 4000
    phi = np.exp(-dt / T)
    x = rng.standard_normal(reps)
    rows = np.empty((reps, 2 * n))
    for k in range(2 * n):
        x = phi * x + np.sqrt(1 - phi**2) * rng.standard_normal(reps) if k else x
        rows[:, k] = x
    d = rows[:, n:].mean(1) - rows[:, :n].mean(1)
    g = float(half_difference_factor(np.array(n * dt), T))
    assert np.mean(d**2) == pytest.approx(g, rel=4 * np.sqrt(2 / reps) + 0.02)


def test_annotated_hand_held_session_is_not_where_its_labels_say(real: Path, tmp_path: Path) -> None:
    src = real / "imucal-ferraris/annotated_session.csv"
    rec = read_recording(_convert(tmp_path, ["imucal", str(src), "--sample-rate-hz", "204.8"]))
    d = diagnose_recording(rec)
    assert [f.effect for f in d.findings] == ["pose_error"]
    assert d.baseline.chi2_dof > 100 and d.final.chi2_dof < 2
    angles = np.rad2deg(np.array(d.findings[0].parameters["angles_rad"]))
    labels = list(d.labels)
    w = int(np.argmax(np.abs(angles).max(axis=1)))
    assert labels[w] in ("z_p", "z_a") and int(np.argmax(np.abs(angles[w]))) == 0  # about x
    # Independent: the first-order (OLS) fit's y residual in the z poses, as an angle about x.
    ev = recording_evidence(rec)
    X = first_order_design(ev.f_m_s2)
    th = np.linalg.lstsq(X, ev.y.reshape(-1), rcond=None)[0]
    r = (ev.y.reshape(-1) - X @ th).reshape(-1, 3)
    implied = np.rad2deg(np.abs(r[labels.index("z_p"), 1]) / (abs(th[3 + 4]) * ev.g_local_m_s2))
    assert 0.2 < implied < 2.0
    assert 0.5 * implied < abs(angles[w, 0]) < 2.0 * implied


def test_ferraris_session_in_m_s2_has_no_supported_finding(real: Path, tmp_path: Path) -> None:
    src = real / "imucal-ferraris/example_ferraris_session.csv"
    path = _convert(tmp_path, ["imucal", str(src), "--sample-rate-hz", "102.4"])
    d = diagnose_recording(read_recording(path))
    assert d.findings == ()
    assert d.baseline.chi2_dof < 5


def test_xsens_orientation_free_session(real: Path, tmp_path: Path) -> None:
    s = real / "imu_tk-xsens"
    units = ["--channel-unit", "count", "--gyro-unit", "count", "--g-local-m-s2", "9.81744"]
    path = _convert(tmp_path, ["imu_tk", str(s / "xsens_acc.mat"), str(s / "xsens_gyro.mat"), *units])
    d = diagnose_recording(read_recording(path))
    assert d.method == "orientation-free" and "pose_error" in d.unobservable
    assert d.findings == () and d.final.chi2_dof < 2
    assert d.unexplained is None  # only magnitudes are tested without known orientations


def test_independent_example_with_no_effect_gives_no_finding(independent_dir: Path) -> None:
    """example_static12 (independent simulator, truth: no effect, its .truth.json): no catalogue
    finding and no library term. Its z channel's trend once passed as ``abs(f_y)*t`` on az
    (likelihood ratio 39.5 with the slow noise collapsed to 1.6e-10 V); beside the trend a
    wander makes on az its pose-modulated part is noise, and the note says so."""
    ex = independent_dir
    truth = json.loads((ex / "example_static12.truth.json").read_text())
    assert truth["effects"] == []
    d = diagnose_recording(read_recording(ex / "example_static12.csv"))
    assert d.findings == () and d.discovered == () and d.unexplained is None
    note = next(n for n in d.notes if n.startswith("abs(f_y)*t[az]:"))
    assert "cannot tell abs(f_y)*t[az] from a wander" in note
    # the final model's slow noise is the wander the recording shows, not a collapsed one
    tau = d.noise_text.split("sigma = [")[1].split("]")[0].split(", ")
    assert min(float(x) for x in tau) > 1e-6
