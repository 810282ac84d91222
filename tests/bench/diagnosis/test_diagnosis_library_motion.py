"""The term library of moving recordings (``library_motion*``): bases, statistics, discoveries.

Fast: the sensor-axis rate and acceleration against the attitude and encoder rates computed
another way (kinematics, Savitzky–Golay of the angles); ḟ against a numerical derivative of
the modelled specific force; the library's terms against their definitions; the blocks'
Satterthwaite dof in closed form; catalogue effects at 10x their limit named as the catalogue
effect with nothing discovered; the independent simulator's rate-table example. Slow: terms
concealed in simulated oscillations (added to the raw channel sample by sample from the
recording's own encoder angles; the simulator knows only the catalogue), a one-channel delay
(the simulator's own delay applied to one channel), and 20 clean recordings.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import savgol_filter

from bench.calibration.diagnose import diagnose_recording
from bench.calibration.windows import moving_samples
from bench.diagnosis.bench_families import FINDING_PARAMETERS
from bench.diagnosis.dynamic import select_terms
from bench.diagnosis.library_motion import candidate_terms, force_rate, motion_bases, sensor_rates
from bench.diagnosis.library_motion_scores import BaseColumns, Design, satterthwaite_dof
from bench.estimation.dynamic_model import specific_force
from bench.kinematics import angular_velocity, attitude
from bench.recording import Recording, read_recording
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, moving_recording

G0 = 9.80665
_BASE = r"(abs\(f_[xyz]\)|f_[xyz]|temp|t|w_[xyz]|dw_[xyz]|fdot_[xyz])(\^\d)?"
GRAMMAR = re.compile(rf"^{_BASE}(\*{_BASE})*$")


def _rates_another_way(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Sensor-axis ω (rad/s) and ω̇ (rad/s²): ω_base = Σ θ̇_i a_i from Savitzky–Golay rates of the
    encoder angles, turned into sensor axes by Rᵀ (R the sensor attitude), then differentiated."""
    geo = rec.sidecar.table
    assert geo is not None
    q = rec.table_rad_unwrapped()
    assert q is not None
    h = float(np.median(np.diff(rec.t_s)))
    wb = angular_velocity(geo.axis_vectors, q, savgol_filter(q, 9, 3, deriv=1, delta=h, axis=0))
    R = attitude(geo.axis_vectors, q, geo.mount_matrix)
    w = np.einsum("nji,nj->ni", R, wb)
    return w, np.gradient(w, rec.t_s, axis=0)


def _gravity_in_sensor_axes_g(rec: Recording) -> np.ndarray:
    geo = rec.sidecar.table
    assert geo is not None
    R = attitude(geo.axis_vectors, rec.table_rad_unwrapped(), geo.mount_matrix)
    return np.asarray(R[:, 2, :])  # Rᵀ e_z: gravity's direction in sensor axes (g)


def test_sensor_rates_agree_with_the_attitude_and_the_encoder_rates() -> None:
    rec = moving_recording({}, 13)
    m, _ = moving_samples(rec)
    w, dw = sensor_rates(m)
    w2, dw2 = _rates_another_way(rec)
    v = m.valid
    inner = v & (np.arange(m.n) > 20) & (np.arange(m.n) < m.n - 20)
    assert np.max(np.abs(w[inner] - w2[inner])) < 2e-3 * np.max(np.abs(w2))
    assert np.max(np.abs(dw[inner] - dw2[inner])) < 2e-2 * np.max(np.abs(dw2))
    assert np.max(np.abs(w2)) > 0.5  # the oscillation turns at ~1 rad/s: the check has teeth


def test_force_rate_is_the_time_derivative_of_the_modelled_specific_force() -> None:
    rec = moving_recording({}, 13)
    m, y = moving_samples(rec)
    fit = select_terms(m, y, rec.sidecar.g_local_m_s2, np.zeros(3)).fits[-1]
    fdot = force_rate(fit, m, rec.sidecar.g_local_m_s2, np.zeros(3))
    f = specific_force(fit.theta, m, fit.spec, rec.sidecar.g_local_m_s2, np.zeros(3))
    num = np.gradient(f, m.t_s, axis=0)
    inner = m.valid & (np.arange(m.n) > 20) & (np.arange(m.n) < m.n - 20)
    assert np.max(np.abs(fdot[inner] - num[inner])) < 1e-2 * np.max(np.abs(num[inner]))


def test_library_leaves_out_the_model_the_static_catalogue_and_slow_trends() -> None:
    rec = moving_recording({}, 13)
    m, y = moving_samples(rec)
    fit = select_terms(m, y, rec.sidecar.g_local_m_s2, np.zeros(3)).fits[0]
    bases, vals = motion_bases(m, fit, rec.sidecar.g_local_m_s2, np.zeros(3), rec.temp_c)
    terms = candidate_terms(bases)
    labels = {t.label for t in terms}
    assert all(GRAMMAR.match(t.term) for t in terms)
    assert all(t.degree <= 3 for t in terms)
    for ch, a in zip(("ax", "ay", "az"), "xyz", strict=True):
        assert f"f_{a}[{ch}]" not in labels  # the first-order model
        assert f"f_{a}^2[{ch}]" not in labels  # nonlinearity_quadratic
        assert f"abs(f_{a})[{ch}]" not in labels  # scale_asymmetry
        assert f"f_x*f_y[{ch}]" not in labels  # cross_coupling
        assert f"t[{ch}]" not in labels and f"t^2[{ch}]" not in labels  # a wander's trend
        assert f"fdot_{a}[{ch}]" in labels and f"w_z^2[{ch}]" in labels and f"f_x*w_y[{ch}]" in labels
    assert "f_y^2[ax]" in labels  # another axis's square is not the catalogue's
    assert "abs(f_x)^2[ax]" not in labels and "abs(f_x)*abs(f_x)[ax]" not in labels
    assert {"w_x", "dw_y", "fdot_z", "t"} <= set(vals)


def test_a_designs_chunk_values_are_its_products_kept_from_the_second_asking() -> None:
    """The monomials x_a·x_b·x_c / scale at a chunk's rows, worked out here from the bases; kept
    (the same array returned) only once the chunk is asked for again."""
    rng = np.random.default_rng(3)
    cols = tuple(rng.normal(size=50) for _ in range(2))
    index = np.array([[0, 0, 1], [2, 1, 1], [2, 2, 2]])  # x0, x0*x1, x1^2 (2 is the ones column)
    scale = np.array([2.0, 4.0, 8.0])
    d = Design(index, ("x0", "x0*x1", "x1^2"), np.arange(50), 1, np.arange(50), np.zeros((50, 3)),
               scale, np.eye(3), np.zeros(50, dtype=np.int64), 1)  # fmt: skip
    base = BaseColumns(cols)
    rows = np.arange(10, 30)
    want = np.column_stack([cols[0][rows] / 2, cols[0][rows] * cols[1][rows] / 4, cols[1][rows] ** 2 / 8])
    first = d.chunk_values(base, 10, rows)
    np.testing.assert_allclose(first, want, rtol=1e-15)
    assert not d.kept  # a search that stops at its first step keeps nothing
    second = d.chunk_values(base, 10, rows)
    np.testing.assert_array_equal(second, want)
    assert d.chunk_values(base, 10, rows) is second


def test_satterthwaite_dof_of_a_two_lag_bartlett_variance() -> None:
    """Bartlett weights 1, 2/3, 1/3: Σ_{|k|≤2} w_k² = 1 + 2 (4/9 + 1/9) = 19/9."""
    assert satterthwaite_dof(50) == pytest.approx(50 * 9 / 19)


@pytest.mark.parametrize("effect", ["lever_arm", "time_skew"])
def test_catalogue_effect_is_named_as_itself_not_as_library_terms(effect: str) -> None:
    case = DYNAMIC_CASES[effect]
    d = diagnose_recording(case.recording(10 * case.limit, seed=11))
    assert [f.effect for f in d.findings] == [case.finding]
    assert d.discovered == () and d.unexplained is None


def test_independent_rate_example_gives_no_discovered_term(independent_dir: Path) -> None:
    """``example_rate_lever_known`` (another simulator, lever arm (60, 0, −15) mm known in its
    sidecar): the catalogue claims nothing, the library adds nothing, the model fits."""
    d = diagnose_recording(read_recording(independent_dir / "example_rate_lever_known.csv"))
    assert d.method == "dynamic"
    assert d.findings == () and d.discovered == () and d.unexplained is None


@pytest.mark.slow
def test_one_channel_delay_is_discovered_as_fdot_on_its_channel() -> None:
    """ax delayed 5 ms behind ay, az: the simulator's own delay (``time_skew``, which moves the
    signal and not the noise) applied to ax alone. Expected: fdot_x on ax with coefficient
    −0.005 s · K_xx · g0 within 3 of its sigmas, the catalogue's time skew (and the lever arm and
    proof masses that first took the rest) replaced, no ``unexplained``."""
    seed = 7
    clean = moving_recording({}, seed)
    raw = clean.accel_raw.copy()
    raw[:, 0] = moving_recording({"time_skew": {"delay_s": 0.005}}, seed).accel_raw[:, 0]
    d = diagnose_recording(replace(clean, accel_raw=raw))
    assert [(x.channel, x.term) for x in d.discovered] == [("ax", "fdot_x")]
    x = d.discovered[0]
    scale = d.K[0, 0] * G0  # channel units per g
    assert abs(x.coefficient / scale - (-0.005)) < 3 * x.sigma / scale
    assert x.sigma / scale < 2e-4
    assert "delay of the x channel" in x.physics
    assert d.findings == () and d.unexplained is None
    assert d.final.chi2_dof < 1.1 < d.baseline.chi2_dof
    c = diagnose_recording(clean)
    assert c.discovered == () and c.unexplained is None


CONCEALED = {
    # w_z² on az: a bias following the rate squared, outside the proof masses' span on az
    # (on ay it lies 0.99 inside it: a y offset along y gives −(ω_x² + ω_z²) there, ω_x small)
    "w_z^2": ("az", 3e-4, lambda w, f: w[:, 2] ** 2),
    # f_x·ω_y on ax: ḟ_z = ω_y f_x − ω_x f_y makes f_x·ω_y partly a rate of change of f_z
    "f_x*w_y": ("ax", 3e-4, lambda w, f: f[:, 0] * w[:, 1]),
}


@pytest.mark.slow
@pytest.mark.parametrize("term", sorted(CONCEALED))
def test_concealed_motion_term_is_named_on_its_channel_within_its_sigma(term: str) -> None:
    channel, coef, values = CONCEALED[term]
    ch = ("ax", "ay", "az").index(channel)
    for seed in (7, 8):
        rec = moving_recording({}, seed)
        w, _ = _rates_another_way(rec)
        raw = rec.accel_raw.copy()
        raw[:, ch] += coef * values(w, _gravity_in_sensor_axes_g(rec))
        d = diagnose_recording(replace(rec, accel_raw=raw))
        named = [
            x for x in d.discovered if x.channel == channel and (x.term == term or term in x.confounded_with)
        ]
        assert named, (seed, [(x.channel, x.term) for x in d.discovered], [f.effect for f in d.findings])
        assert d.findings == (), (seed, [f.summary for f in d.findings])
        x = named[0]
        if x.term == term:
            assert abs(x.coefficient - coef) < 3 * x.sigma, (seed, x.coefficient, x.sigma)
        assert d.unexplained is None


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_twenty_clean_moving_recordings_discover_nothing() -> None:
    """No catalogue claim and no library term on twenty clean recordings. The bench-physics
    stage after the model (angle harmonics, clock drift, lines: ``bench_families``) tests each
    family at ``bench_false_alarm`` (1e-3) per recording, 3e-3 for the three: over twenty
    recordings at most one such finding (P(≥ 2) = 0.17 % at that rate)."""
    claims, bench = {}, {}
    for kind in ("oscillation", "rate"):
        for seed in range(40, 50):
            d = diagnose_recording(moving_recording({}, seed, kind=kind))
            found = [f.effect for f in d.findings if f.effect not in FINDING_PARAMETERS]
            found += [f"{x.term}[{x.channel}]" for x in d.discovered]
            if found:
                claims[(kind, seed)] = found
            if extra := [f.effect for f in d.findings if f.effect in FINDING_PARAMETERS]:
                bench[(kind, seed)] = extra
    assert not claims, claims
    assert len(bench) <= 1, bench


@pytest.mark.slow
def test_score_statistic_holds_its_level_under_serially_correlated_noise() -> None:
    """The model's own prediction plus AR(1) noise (φ = 0.95 per 10 ms sample: a correlation
    time of 0.2 s, 20 samples): for three candidates on ax, T against the 5 % point of
    F(1, ν) rejects about 5 % of 150 draws (2–10 % allowed: 450 correlated tests), while the
    white-noise statistic U²/ãᵀWã against χ²_1 rejects far more (the variance of a sum of
    AR(1) samples is (1 + φ)/(1 − φ) = 39 times the white one)."""
    from scipy.signal import lfilter
    from scipy.stats import chi2
    from scipy.stats import f as f_dist

    from bench.diagnosis.library_motion_scores import design, scores
    from bench.estimation.dynamic_model import predict

    rec = moving_recording({}, 13)
    m, y = moving_samples(rec)
    g = rec.sidecar.g_local_m_s2
    fit = select_terms(m, y, g, np.zeros(3)).fits[0]
    bases, vals = motion_bases(m, fit, g, np.zeros(3), rec.temp_c)
    by = {b.name: b for b in bases}
    monos = [(by["fdot_x"],), (by["w_z"], by["w_z"]), (by["f_x"], by["w_y"])]
    des, base = design(m, monos, vals)
    model, _ = predict(fit.theta, m, fit.spec, g, np.zeros(3))
    phi, sd = 0.95, 1e-3
    fit = replace(fit, noise_sigma=np.full(3, sd))
    rng = np.random.default_rng(5)
    T, Tw = [], []
    for _ in range(150):
        white_noise = rng.normal(0.0, sd * np.sqrt(1 - phi**2), (m.n + 500, 3))
        e = lfilter([1.0], [1.0, -phi], white_noise, axis=0)[500:]  # 500 samples of burn-in
        st = scores(m, model + e, fit, g, np.zeros(3), [], des, base, vals, None)
        T.extend(st.U[0] ** 2 / st.V[0])
        Tw.extend(st.U[0] ** 2 / np.diag(st.P[0]))
    nu = satterthwaite_dof(st.n_blocks)
    hac = float(np.mean(np.array(T) > f_dist.ppf(0.95, 1, nu)))
    white = float(np.mean(np.array(Tw) > chi2.ppf(0.95, 1)))
    assert 0.02 < hac < 0.10, hac
    assert white > 0.4, white
