"""The planner: window-mean covariance, predicted fit covariance, bound, search, CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

import api.cli
from bench.planning.evaluation import WINDOW_TILT_NOTE, Targets, evaluate
from bench.planning.information import predicted_uncertainty, time_for_k, white_bound_k
from bench.planning.noise import G0_M_S2, UnitNoise, window_mean_covariance
from bench.planning.search import plan
from bench.procedures import build_procedure, preview
from bench.procedures.planned import EXECUTION_ORDER, planned_static, planned_tumble, visit_order
from bench.procedures.static import icosahedron_up_directions
from bench.procedures.steps import Dwell, MoveTo, Procedure


def _brute_covariance(noise: UnitNoise, starts: np.ndarray, durs: np.ndarray, dt: float) -> np.ndarray:
    """Window-mean covariance by summing the kernels on a fine grid (midpoint rule)."""
    grids = [a + dt * (np.arange(round(T / dt)) + 0.5) for a, T in zip(starts, durs, strict=True)]
    m = len(grids)
    C = np.zeros((m, m))
    for i in range(m):
        for j in range(m):
            t, s = grids[i][:, None], grids[j][None, :]
            k = noise.wander_m_s2**2 * np.exp(-np.abs(t - s) / noise.wander_tau_s)
            k = k + noise.random_walk_m_s2_rt_s**2 * np.minimum(t, s)
            C[i, j] = k.mean()
    return C + np.diag(noise.white_m_s2_rt_hz**2 / durs)


def test_window_mean_covariance_is_the_kernel_integrated_over_the_windows() -> None:
    noise = UnitNoise(2e-3, wander_m_s2=4e-4, wander_tau_s=30.0, random_walk_m_s2_rt_s=5e-5)
    starts = np.array([0.0, 12.0, 15.0, 70.0])
    durs = np.array([10.0, 3.0, 40.0, 5.0])
    got = window_mean_covariance(noise, starts, durs)
    want = _brute_covariance(noise, starts, durs, 0.01)
    np.testing.assert_allclose(got, want, rtol=1e-4)
    with pytest.raises(ValueError, match="overlap"):
        window_mean_covariance(noise, np.array([0.0, 5.0]), np.array([10.0, 1.0]))


def test_white_noise_icosahedron_reaches_the_isotropic_formula() -> None:
    # linear-model Cramér-Rao bound, isotropic poses, white noise:
    # sd(M_ij) = √3 σ_mean / (g √N), sd(b) = σ_mean/√N
    g, sigma_mean = 9.8, 1e-3
    f = g * icosahedron_up_directions()
    u = predicted_uncertainty(f, sigma_mean**2 * np.eye(12))
    np.testing.assert_allclose(u.k_elements, math.sqrt(3) * sigma_mean / (g * math.sqrt(12)), rtol=1e-9)
    np.testing.assert_allclose(u.bias_m_s2, sigma_mean / math.sqrt(12), rtol=1e-9)


def test_white_bound_is_the_known_value_and_inverts() -> None:
    n = 250e-6 * G0_M_S2  # 250 µg/√Hz over 40 min: 8.84 ppm (√3·250e-6/√2400)
    assert white_bound_k(n, 2400.0, G0_M_S2) == pytest.approx(8.839e-6, rel=1e-3)
    assert time_for_k(n, 8.839e-6, G0_M_S2) == pytest.approx(2400.0, rel=1e-3)


def test_predicted_sigma_matches_a_sample_level_simulation() -> None:
    """Sample-level white + Gauss-Markov noise at 20 Hz, window means fitted by GLS with the
    predicted covariance: the K errors' spread over 60 seeds matches the prediction (z spread
    within 0.75–1.3, the sampling band of a 60-seed, 9-element spread is about ±0.1)."""
    rng = np.random.default_rng(7)
    fs, noise = 20.0, UnitNoise(5e-3, wander_m_s2=2e-3, wander_tau_s=40.0)
    proc = planned_static(dwell_s=4.0, repeats=2, settle_s=1.0)
    e = evaluate(proc, noise, with_tilt=False)
    pv = preview(proc)
    starts = np.array([w.start_s for w in pv.windows])
    idx = [np.arange(round(a * fs), round((a + 4.0) * fs)) for a in starts]
    n = round(pv.duration_s * fs) + 1
    C = window_mean_covariance(noise, starts, np.full(starts.size, 4.0))
    dirs = icosahedron_up_directions()[visit_order(2)] * G0_M_S2
    X = np.column_stack([np.ones(len(dirs)), dirs])
    Ci = np.linalg.inv(C)
    A = np.linalg.solve(X.T @ Ci @ X, X.T @ Ci)
    phi = math.exp(-1 / (fs * noise.wander_tau_s))
    z = []
    for _ in range(60):
        white = rng.normal(0, noise.white_m_s2_rt_hz * math.sqrt(fs), (n, 3))
        w = rng.normal(0, noise.wander_m_s2 * math.sqrt(1 - phi**2), (n, 3))
        gm = np.empty((n, 3))
        gm[0] = rng.normal(0, noise.wander_m_s2, 3)
        for k in range(1, n):
            gm[k] = phi * gm[k - 1] + w[k]
        means = np.stack([(white + gm)[ix].mean(axis=0) for ix in idx])
        kerr = (A @ means)[1:].T  # (3 channels, 3 force components): K error, truth K = I
        z.append(kerr / e.predicted.k_elements)
    spread = float(np.std(np.array(z)))
    assert 0.75 < spread < 1.3, spread


def test_planned_static_keeps_antipodes_adjacent_and_repeats() -> None:
    proc = planned_static(dwell_s=5.0, repeats=3)
    assert proc.n_windows == 36 and visit_order(3)[12:24] == list(reversed(EXECUTION_ORDER))
    dirs = icosahedron_up_directions()[visit_order(3)]
    for i in range(0, 36, 2):
        np.testing.assert_allclose(dirs[i], -dirs[i + 1], atol=1e-12)
    assert build_procedure("planned-static", dwell_s=5.0, repeats=3) == proc
    with pytest.raises(ValueError, match="repeats"):
        planned_static(repeats=0)


def test_plan_is_the_fewest_passes_that_meet_the_target() -> None:
    noise = UnitNoise.from_ug(250, 40, 200)
    target = Targets(scale=60e-6, misalignment_rad=60e-6)
    got = plan(noise, target, max_duration_s=1800.0)
    assert got.best is not None
    best = got.best
    assert target.met_by(best.predicted) and best.duration_s <= 1800.0
    reps = int(best.procedure.parameters["repeats"])  # type: ignore[call-overload]
    if reps > 1:
        dwell = float(best.procedure.parameters["dwell_s"])  # type: ignore[arg-type]
        fewer = evaluate(planned_static(dwell_s=dwell, repeats=reps - 1), noise)
        assert not target.met_by(fewer.predicted)
    assert 1.0 <= best.k_fraction_of_bound < 1.3
    none = plan(noise, Targets(scale=1e-7), max_duration_s=600.0)
    assert none.best is None and none.closest is not None and "10 min" in none.problems[0]


def test_cli_plan_prints_a_plan_and_refuses_bad_input(capsys: pytest.CaptureFixture[str]) -> None:
    rc = api.cli.main(["plan", "--white", "250", "--wander", "40", "--wander-tau", "200", "--scale", "80",
                       "--max-minutes", "20", "--json"])  # fmt: skip
    assert rc == 0
    import json

    out = json.loads(capsys.readouterr().out)
    # both families are planned; the tumble fitted by every sample also uses the moves: shorter
    assert out["plan"]["procedure"] == "planned-tumble" and out["plan"]["fit"] == "every-sample"
    assert out["plan"]["predicted_U_k2"]["scale_ppm"] <= 80 and out["start"]["procedure"] == "planned-tumble"
    rc = api.cli.main(["plan", "--white", "250", "--wander", "40", "--wander-tau", "200", "--scale", "80",
                       "--max-minutes", "20", "--json", "--fit", "window"])  # fmt: skip
    window = json.loads(capsys.readouterr().out)["plan"]
    assert rc == 0 and window["procedure"] == "planned-static" and window["fit"] == "window"
    assert window["duration_s"] > out["plan"]["duration_s"]
    assert api.cli.main(["plan", "--white", "250"]) == 2
    assert "at least one" in capsys.readouterr().err


def test_predicted_and_achieved_states_u_relative_to_the_fitted_scale() -> None:
    from bench.planning.report import predicted_and_achieved

    K = np.diag([2.0, 2.0, 4.0])
    K_sigma = np.full((3, 3), 1e-6)
    K_sigma[2, 1] = 8e-6  # 2e-6 relative to K_zz = 4: the largest off-diagonal
    bias_sigma = np.array([2.0 * G0_M_S2 * 1e-6, 0.0, 0.0])  # 1 µg at scale 2
    out = predicted_and_achieved({"predicted_scale_u_ppm": 3.0}, K, K_sigma, bias_sigma)
    assert out["scale_ppm"] == {"predicted": 3.0, "achieved": pytest.approx(1.0)}  # 2 × 1e-6 / 2
    assert out["misalignment_urad"]["achieved"] == pytest.approx(4.0)
    assert out["bias_ug"]["achieved"] == pytest.approx(2.0) and out["bias_ug"]["predicted"] is None


def test_from_allan_terms_matches_the_gauss_markov_peak_to_the_floor() -> None:
    from bench.planning.noise import GM_ALLAN_PEAK, GM_PEAK_TAU, from_allan_terms

    n = from_allan_terms(1e-3, 3e-4, 1e-5, 189.0)
    assert n.white_m_s2_rt_hz == 1e-3 and n.random_walk_m_s2_rt_s == 1e-5
    assert (
        n.wander_m_s2 * GM_ALLAN_PEAK == pytest.approx(0.664 * 3e-4) and n.wander_tau_s * GM_PEAK_TAU == 189.0
    )


def test_cli_plan_takes_the_noise_from_a_recording(
    tmp_path: object, capsys: pytest.CaptureFixture[str]
) -> None:
    """Half an hour of white noise (2e-3 m/s²/√Hz = 204 µg/√Hz) and a bias random walk: the plan's
    noise line gives the white density within 10 %."""
    import json
    from pathlib import Path

    from bench.recording import Recording, Sidecar, write_recording
    from tests.support.noise import rate_random_walk, white

    fs, n_true = 50.0, 2e-3
    rng = np.random.default_rng(5)
    n = 90_000
    a = white(rng, n, fs, n_true, 3) + rate_random_walk(rng, n, fs, 2e-5, 3)
    a[:, 2] += 9.81
    sc = Sidecar(unit_serial="SN-NOISE", channel_unit="m/s2", sample_rate_hz=fs, g_local_m_s2=9.81)
    path = Path(str(tmp_path)) / "noise.csv"
    write_recording(Recording(sidecar=sc, t_s=np.arange(n) / fs, accel_raw=a), path)
    rc = api.cli.main(["plan", "--noise-from", str(path), "--scale", "200", "--max-minutes", "20", "--json"])
    assert rc == 0
    noise = json.loads(capsys.readouterr().out)["noise"]
    white_ug = float(noise.split("white ")[1].split(" ")[0])
    assert white_ug == pytest.approx(n_true / G0_M_S2 * 1e6, rel=0.1), noise
    assert api.cli.main(["plan", "--scale", "200"]) == 2
    assert "--noise-from" in capsys.readouterr().err


def test_the_plan_says_what_its_poses_and_its_fit_cannot_tell_apart() -> None:
    """Six poses with the outer axis never turning determine bias and K, but not a base tilt
    beside them: the evaluation says so and predicts for a level base (the same numbers as
    without the tilt) instead of failing or pretending. A pose set that separates it carries the
    tilt and says the window fit does not estimate it; the every-sample tumble carries the lever
    arm and the tilt as nuisance parameters."""
    noise = UnitNoise.from_ug(250.0, 40.0, 200.0)
    poses = (
        (0.0, 0.0, 0.0),
        (0.0, 180.0, 0.0),
        (0.0, 90.0, 0.0),
        (0.0, -90.0, 0.0),
        (0.0, 90.0, 90.0),
        (0.0, 45.0, 0.0),
    )
    steps: list[MoveTo | Dwell] = []
    for i, p in enumerate(poses):
        steps += [MoveTo(p, f"p{i}"), Dwell(f"p{i}", 10.0)]
    six = Procedure("six", tuple(steps), {"dwell_s": 10.0, "settle_s": 2.0})
    e = evaluate(six, noise)
    assert e.predicted.tilt_rad.size == 0 and "cannot separate a base tilt" in e.notes[0]
    np.testing.assert_array_equal(e.predicted.cov, evaluate(six, noise, with_tilt=False).predicted.cov)
    s = evaluate(planned_static(dwell_s=10.0, repeats=1), noise)
    assert s.predicted.tilt_rad.size == 2 and s.notes == (WINDOW_TILT_NOTE,)
    t = evaluate(planned_tumble(dwell_s=3.0, repeats=1), noise, fit="every-sample")
    assert t.predicted.nuisance.size == 5 and t.notes == ()
