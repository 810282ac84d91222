"""Procedures as data: poses, spreads, durations and limit checks, checked independently."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.procedures import (
    DEFAULT_TABLE_LIMITS,
    PROCEDURES,
    Dwell,
    MoveTo,
    NoiseWindow,
    Oscillate,
    Procedure,
    Rotate,
    TableLimits,
    build_procedure,
    preview,
)
from bench.procedures.oscillation import T1_S, T2_S
from bench.procedures.preview import move_time_s
from bench.records import WindowKind

AXES = np.array([[0, 0, 1], [1, 0, 0], [0, 0, 1]], dtype=float)  # docs/recording-format.md default


def gravity_in_sensor(angles_deg: tuple[float, ...], tilt_rad: tuple[float, float] = (0, 0)) -> np.ndarray:
    """f/g = Rᵀ·ĝ with R = Rot(u1,θ1)·Rot(u2,θ2)·Rot(u3,θ3), built with scipy (independent of the code)."""
    r = Rotation.identity()
    for u, th in zip(AXES, angles_deg, strict=True):
        r = r * Rotation.from_rotvec(u * math.radians(th))
    up = Rotation.from_rotvec([tilt_rad[0], 0, 0]) * Rotation.from_rotvec([0, tilt_rad[1], 0])
    return r.inv().apply(up.apply([0.0, 0.0, 1.0]))


def static_poses() -> list[tuple[float, ...]]:
    proc = build_procedure("static-12", dwell_s=30.0)
    return [s.angles_deg for s in proc.steps if isinstance(s, MoveTo)]


def test_static12_visits_the_icosahedron() -> None:
    f = np.array([gravity_in_sensor(p) for p in static_poses()])
    assert f.shape == (12, 3)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1.0, atol=1e-9)
    # Regular icosahedron: every vertex has 5 neighbours at arccos(1/sqrt5) = 63.435 deg,
    # the directions sum to zero and their scatter matrix is isotropic, sum f fᵀ = 12/3 I.
    cos = f @ f.T
    nearest = np.sort(np.degrees(np.arccos(np.clip(cos, -1, 1))), axis=1)[:, 1:6]
    np.testing.assert_allclose(nearest, math.degrees(math.acos(1 / math.sqrt(5))), atol=1e-4)
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9)
    np.testing.assert_allclose(f.T @ f, 4.0 * np.eye(3), atol=1e-9)


def test_static12_identifies_bias_and_full_scale_matrix() -> None:
    f = np.array([gravity_in_sensor(p) for p in static_poses()])
    design = np.hstack([np.ones((12, 1)), f])
    assert np.linalg.matrix_rank(design) == 4
    assert np.linalg.cond(design) < 2.0


def _unexplained_tilt_fraction(poses: list[tuple[float, ...]], tilt_rad: tuple[float, float]) -> float:
    """Part of a small tilt's signature that misalignment and encoder offsets cannot absorb.

    The change a tilt makes to f is fitted by a constant sensor-frame rotation (absorbed by
    K's off-diagonal terms) plus middle and inner encoder offsets (linearised numerically).
    """
    f = np.array([gravity_in_sensor(p) for p in poses])
    d = np.concatenate([gravity_in_sensor(p, tilt_rad) - gravity_in_sensor(p) for p in poses])
    rotation_cols = np.vstack([np.cross(np.eye(3), fi).T for fi in f])
    h_deg = 1e-4
    offset_cols = [
        np.concatenate(
            [
                (gravity_in_sensor(tuple(np.add(p, np.eye(3)[k] * h_deg))) - gravity_in_sensor(p))
                / math.radians(h_deg)
                for p in poses
            ]
        )
        for k in (1, 2)
    ]
    a = np.column_stack([rotation_cols, *offset_cols])
    coef, *_ = np.linalg.lstsq(a, d, rcond=None)
    return float(np.linalg.norm(d - a @ coef) / np.linalg.norm(d))


def test_static12_outer_axis_makes_base_tilt_observable() -> None:
    poses = static_poses()
    assert len({p[0] for p in poses}) == 4
    for tilt in ((1e-3, 0.0), (0.0, 1e-3)):
        assert _unexplained_tilt_fraction(poses, tilt) > 0.5
    # Control: with the outer axis held at 0, a tilt about x is exactly a middle-encoder offset.
    fixed = [(0.0, *p[1:]) for p in poses]
    assert _unexplained_tilt_fraction(fixed, (1e-3, 0.0)) < 1e-2


def test_static12_with_noise_window_first() -> None:
    proc = build_procedure("static-12")
    kinds = [s.kind for _, s in proc.window_steps()]
    assert kinds[0] is WindowKind.NOISE and kinds.count(WindowKind.STATIC) == 12
    assert proc.needs_dwell()
    assert not build_procedure("static-12", dwell_s=20.0).needs_dwell()


def test_rate_1axis_reaches_200_deg_s_and_puts_every_axis_in_the_rotation_plane() -> None:
    proc = build_procedure("rate-1axis", dwell_s=10.0)
    rotates = [s for s in proc.steps if isinstance(s, Rotate)]
    assert max(abs(r.rate_deg_s) for r in rotates) == 200.0
    assert {r.axis for r in rotates} == {1}
    assert sorted(r.rate_deg_s for r in rotates) == sorted(-r.rate_deg_s for r in rotates)
    ups = [gravity_in_sensor(s.angles_deg) for s in proc.steps if isinstance(s, MoveTo)]
    for axis in range(3):  # a sensor axis is horizontal (in the plane of rotation) in some pose
        assert any(abs(u[axis]) < 1e-9 for u in ups)
    assert preview(proc).ok


def test_rate_1axis_tilted_poses_double_the_pose_set() -> None:
    base = build_procedure("rate-1axis", dwell_s=10.0)
    tilted = build_procedure("rate-1axis", dwell_s=10.0, tilted_deg=7.0)
    assert tilted.n_windows == 2 * base.n_windows


def test_oscillation_2axis_follows_the_paper() -> None:
    proc = build_procedure("oscillation-2axis", dwell_s=10.0)
    (osc,) = [s for s in proc.steps if isinstance(s, Oscillate)]
    assert math.isclose(2 * T1_S, 5 * T2_S) and T2_S == 12.0
    assert sorted(osc.amplitudes_deg) == [90.0, 360.0]
    assert osc.peak_rate_deg_s() == pytest.approx((2 * math.pi * 360 / 30, 2 * math.pi * 90 / 12))
    pv = preview(proc)
    assert pv.ok, pv.problems
    # The middle axis swings 0..180 deg about 90 deg: z goes from up to down.
    assert gravity_in_sensor((0, 0, 0))[2] == pytest.approx(1)
    assert gravity_in_sensor((0, 180, 0))[2] == pytest.approx(-1)


def test_move_time_trapezoid_and_triangle() -> None:
    # v=10, a=5: ramp takes 2 s over 10 deg. 100 deg: 10 + 2 = 12 s. 5 deg: triangle 2*sqrt(1) = 2 s.
    assert move_time_s(100, 10, 5) == pytest.approx(12.0)
    assert move_time_s(5, 10, 5) == pytest.approx(2.0)
    assert move_time_s(20, 10, 5) == pytest.approx(4.0)  # boundary: both formulas agree


def test_preview_duration_of_a_small_procedure() -> None:
    limits = TableLimits((-180.0,) * 2, (180.0,) * 2, (10.0, 20.0), (5.0, 5.0), (False, False))
    proc = Procedure(
        "t",
        (MoveTo((100.0, 20.0), "a", settle_s=1.0), Dwell("a", 7.0), Rotate(2, 10.0, 4.0, "r", spinup_s=0.5)),
        {},
        n_axes=2,
    )
    pv = preview(proc, limits)
    # move: axis 1 12 s, axis 2 (v=20, a=5): 20 < 80 -> 2*sqrt(4) = 4 s; +1 settle; dwell 7;
    # rotate 0.5 + 4 + 10/5 decel.
    assert pv.duration_s == pytest.approx(12 + 1 + 7 + 0.5 + 4 + 2)
    assert [w.label for w in pv.windows] == ["a", "r"]
    assert pv.windows[1].start_s == pytest.approx(20.5)
    # rotating 10 deg/s for 4.5 s from 20 deg stays inside +-180: fine
    assert pv.ok, pv.problems


def test_preview_flags_every_kind_of_limit_violation() -> None:
    limits = DEFAULT_TABLE_LIMITS
    proc = Procedure(
        "bad",
        (
            MoveTo((0.0, 190.0, 0.0), "far"),
            MoveTo((0.0, 90.0, 0.0), "ok"),
            Rotate(1, 400.0, 5.0, "fast"),
            Rotate(4, 10.0, 5.0, "noaxis"),
            Oscillate((2,), (120.0,), (1.0,), 10.0, "wild"),
            Rotate(2, 100.0, 5.0, "wrap"),
        ),
        {},
        n_axes=3,
    )
    pv = preview(proc, limits)
    text = "\n".join(pv.problems)
    assert "axis 2 angle 190 deg outside" in text
    assert "rate 400 deg/s exceeds" in text
    assert "axis 4 does not exist" in text
    assert "peak rate" in text and "would swing" in text
    assert "no slip ring" in text
    assert not pv.ok


def test_preview_uses_a_provisional_dwell_and_says_so() -> None:
    pv = preview(build_procedure("static-12"), provisional_dwell_s=45.0)
    pv_fixed = preview(build_procedure("static-12", dwell_s=45.0))
    assert pv.assumptions and "45 s" in pv.assumptions[0]
    assert pv.duration_s == pytest.approx(pv_fixed.duration_s + 120.0)  # + the noise window


@pytest.mark.parametrize("name", sorted(PROCEDURES))
def test_every_procedure_previews_within_default_limits(name: str) -> None:
    for dwell in (None, 15.0):
        pv = preview(build_procedure(name, dwell_s=dwell))
        assert pv.ok, pv.problems
        assert pv.duration_s > 0 and pv.windows


def test_resume_plan_restarts_at_the_move_before_the_window() -> None:
    proc = build_procedure("static-12")  # move, noise, dwell, move, dwell, ...
    assert proc.resume_plan(0) == (1, 0)
    assert proc.resume_plan(1) == (2, 0)
    assert proc.resume_plan(2) == (4, 3)
    assert proc.resume_plan(proc.n_windows) == (len(proc.steps), None)
    with pytest.raises(ValueError, match="cannot resume at window 99"):
        proc.resume_plan(99)


def test_unknown_procedure_and_bad_steps_are_rejected() -> None:
    with pytest.raises(ValueError, match="unknown procedure 'static-13'; known: oscillation-2axis"):
        build_procedure("static-13")
    with pytest.raises(ValueError, match="finite"):
        MoveTo((0.0, math.nan, 0.0))
    with pytest.raises(ValueError, match="> 0"):
        NoiseWindow(0.0)
    with pytest.raises(ValueError, match="same"):
        Oscillate((1, 2), (10.0,), (5.0, 5.0), 10.0)
    with pytest.raises(ValueError, match="axis numbers start at 1"):
        Rotate(0, 10.0, 1.0)


def test_step_kinds_are_distinct() -> None:
    kinds = {
        NoiseWindow(1.0).kind,
        Dwell("d").kind,
        Rotate(1, 1.0, 1.0).kind,
        Oscillate((1,), (1.0,), (1.0,), 1.0).kind,
    }
    assert len(kinds) == 4
    assert all(a != b for a, b in itertools.combinations(kinds, 2))


def test_static12_antipodes_follow_each_other_and_a_trend_stays_out_of_k() -> None:
    """A bias ramp over the run changes the least-squares K by ≤ 0.06 of its rise / g (ring order: 1.06)."""
    f = np.array([gravity_in_sensor(p) for p in static_poses()])
    for i in range(0, 12, 2):
        np.testing.assert_allclose(f[i], -f[i + 1], atol=1e-9)
    design = np.hstack([np.ones((12, 1)), f])
    ramp = np.linspace(-0.5, 0.5, 12)  # one unit of bias change from the first pose to the last
    k_leak = np.linalg.lstsq(design, ramp, rcond=None)[0][1:]
    assert np.linalg.norm(k_leak) < 0.06
    ring = np.hstack([np.ones((12, 1)), f[np.argsort(-f[:, 2], kind="stable")]])
    assert np.linalg.norm(np.linalg.lstsq(ring, ramp, rcond=None)[0][1:]) > 0.5


def test_an_oscillation_ends_with_the_stop_from_its_peak_rate() -> None:
    limits = TableLimits((-180.0,) * 2, (180.0,) * 2, (100.0, 100.0), (5.0, 10.0), (True, True))
    osc = Oscillate((1, 2), (30.0, 10.0), (6.0, 2.0), 12.0, "o")
    pv = preview(Procedure("t", (osc,), {}, n_axes=2), limits)
    # peaks 2π·30/6 = 10π and 2π·10/2 = 10π deg/s; stops 10π/5 and 10π/10 s: the slower is 2π s
    assert pv.duration_s == pytest.approx(12.0 + 2 * math.pi)


def test_a_dwell_not_chosen_yet_is_the_longest_the_noise_window_can_choose() -> None:
    proc = build_procedure("oscillation-2axis", noise_window_s=60.0)
    pv = preview(proc, sample_rate_hz=250.0)
    assert preview(proc, provisional_dwell_s=4096 / 250).duration_s == pytest.approx(pv.duration_s)
    assert "16.384 s assumed (the longest the 60 s noise window can choose)" in pv.assumptions[0]
    # at 100 Hz the octave τ stops at 2048 samples, 20.48 s
    assert preview(proc, sample_rate_hz=100.0).duration_s == pytest.approx(
        pv.duration_s + 2 * (20.48 - 16.384)
    )
