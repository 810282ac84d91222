"""No silent losses: a declared window that is not used is named, a fit without redundancy says so."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from api.cli import main
from bench.calibration import calibrate_recording
from bench.calibration.diagnose import diagnose_recording
from bench.calibration.kind import FitKind
from bench.calibration.windows import MIN_WINDOW_SAMPLES, choose_windows
from bench.recording import Recording, Segment, Sidecar, write_recording
from tests.support.static_sim import G_LOCAL, random_truth

FS = 100.0


def _poses(f: np.ndarray, b: np.ndarray, K: np.ndarray, rng, short: int | None = None) -> Recording:
    """Hand-placed still poses of 3 s (no table, no labels) with 1 s of handling between;
    pose ``short`` is declared over 2 samples only."""
    n_dwell, n_gap = 300, 100
    rows, segs, t0 = [], [], 0
    for w, fw in enumerate(f):
        rows.append(b + K @ fw + rng.normal(0, 0.05, (n_gap, 3)))
        start = t0 + n_gap
        rows.append(b + fw @ K.T + rng.normal(0, 2e-3 * 9.8, (n_dwell, 3)) @ K.T)
        stop = start + (2 if w == short else n_dwell) - 1
        segs.append(Segment(start / FS, stop / FS, f"p{w:02d}"))
        t0 = start + n_dwell
    accel = np.vstack(rows)
    side = Sidecar(
        unit_serial="SN-L", channel_unit="V", sample_rate_hz=FS, g_local_m_s2=G_LOCAL, segments=tuple(segs)
    )
    return Recording(sidecar=side, t_s=np.arange(accel.shape[0]) / FS, accel_raw=accel, source="poses.csv")


def _setup(n: int, short: int | None, seed: int = 7) -> Recording:
    rng = np.random.default_rng(seed)
    b, K = random_truth(rng)
    f = Rotation.random(n, random_state=seed).inv().apply([0.0, 0.0, G_LOCAL])
    return _poses(f, b, K, rng, short=short)


def test_a_short_declared_segment_is_named_and_zero_redundancy_is_flagged() -> None:
    rec = _setup(10, short=4)
    sel = choose_windows(rec)
    assert [u.label for u in sel.unused] == ["p04"] and sel.unused[0].n_samples == 2
    assert f"fewer than the {MIN_WINDOW_SAMPLES}" in sel.unused[0].reason
    res = calibrate_recording(rec)
    assert res.kind is FitKind.ORIENTATION_FREE and len(res.windows) == 9 and res.dof == 0
    # the fit passes through every window: the |g| scatter is zero to rounding
    assert res.g_after.std_m_s2 < 1e-9
    out = res.to_contract()
    assert out["zero_redundancy"] is True and out["dof"] == 0
    assert out["unused_windows"][0]["label"] == "p04" and out["unused_windows"][0]["n_samples"] == 2
    assert any(
        w.startswith("zero redundancy: 9 window magnitudes") and "for 9 parameters" in w
        for w in out["warnings"]
    )
    assert any("'p04'" in w for w in out["warnings"])
    json.dumps(out)


def test_a_redundant_fit_with_every_window_used_has_no_warning() -> None:
    res = calibrate_recording(_setup(12, short=None))
    out = res.to_contract()
    assert out["dof"] == 3 and out["zero_redundancy"] is False
    assert out["unused_windows"] == [] and out["warnings"] == []
    assert res.g_after.std_m_s2 > 1e-6  # three redundant magnitudes: a real scatter


def test_cli_names_the_unused_window_in_text_and_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "poses.csv"
    write_recording(_setup(10, short=4), path)
    assert main(["calibrate", str(path)]) == 0
    text = capsys.readouterr().out
    assert "ZERO REDUNDANCY" in text and "declared windows not used:" in text and "p04" in text
    assert "WARNING: zero redundancy" in text
    assert main(["calibrate", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["zero_redundancy"] is True and [u["label"] for u in out["unused_windows"]] == ["p04"]


def test_diagnose_notes_name_the_unused_window() -> None:
    d = diagnose_recording(_setup(14, short=3))
    assert d.notes[0].startswith("1 declared window(s) not used: 'p03'")


def test_no_usable_window_names_the_ones_left_out() -> None:
    rng = np.random.default_rng(1)
    n = 50
    rec = Recording(
        sidecar=Sidecar(
            unit_serial="S",
            channel_unit="V",
            sample_rate_hz=FS,
            g_local_m_s2=G_LOCAL,
            segments=(Segment(0.0, 0.02, "a"), Segment(0.2, 0.23, "b")),
        ),
        t_s=np.arange(n) / FS,
        accel_raw=rng.normal(size=(n, 3)),
        source="tiny.csv",
    )
    with pytest.raises(ValueError, match=r"^tiny.csv: no static window .*'a': 3 samples.*'b': 4 samples"):
        calibrate_recording(rec)
