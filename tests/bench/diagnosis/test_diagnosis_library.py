"""The term library beyond the catalogue, ``unexplained``, and the pose error as a catch-all.

Fast tests on synthetic static evidence (an ideal triad at 18 directions, white noise): the
library's terms against their definitions, an injected out-of-catalogue term recovered
within its sigma, a one-channel random pattern that neither the library nor a pose error
may claim, the catch-all's effective dof against a finite-difference derivative, and the
per-channel χ² accounts against Monte Carlo. Slow tests: the concealed out-of-catalogue
scenarios of ``benchmarks/library_cases.py`` on simulated static-12 recordings, a per-channel
delay on a moving recording (discovered by the moving library), and the false-finding rate
over 200 clean recordings.
"""

from __future__ import annotations

import numpy as np
import pytest

from api.cli.diagnose import format_human
from bench.diagnosis import StaticEvidence, diagnose
from bench.diagnosis.catch_all import channel_forms, pose_check
from bench.diagnosis.effects import first_order_design, pose_response
from bench.diagnosis.evidence import G0_M_S2
from bench.diagnosis.library import library_terms, term_name, term_unit
from bench.diagnosis.likelihood import NoiseParams, covariance

G = 9.81
DIRS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
     [1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, 1, 0], [-1, 0, -1], [0, -1, 1],
     [1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1], [1, 0, -1], [0, 1, -1]],
    dtype=float,
)  # fmt: skip
SIGMA = 1e-5


def _evidence(
    rng: np.random.Generator, extra: np.ndarray | None = None, dirs: np.ndarray = DIRS
) -> StaticEvidence:
    """Window means of an ideal triad, white noise SIGMA, plus ``extra`` (m, 3) on the raw channels."""
    f = G * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    K = np.diag([0.0177, 0.0175, 0.0178]) + 1e-5
    y = np.array([1.5, 1.49, 1.51]) + f @ K.T + rng.normal(0, SIGMA, f.shape)
    if extra is not None:
        y = y + extra
    m = f.shape[0]
    V = np.broadcast_to(np.eye(3) * SIGMA**2, (m, 3, 3)).copy()
    return StaticEvidence(
        y=y, V=V, f_m_s2=f, mid_s=np.arange(m) * 40.0, labels=tuple(f"w{i}" for i in range(m)), g_local_m_s2=G
    )


def test_library_holds_no_catalogue_term_and_names_in_the_grammar() -> None:
    ev = _evidence(np.random.default_rng(0))
    terms, _ = library_terms(ev)
    by = {(t.channel, t.term) for t in terms}
    # catalogue regressors on their own channel are not library terms
    assert (0, "f_x^2") not in by and (0, "abs(f_x)") not in by and (1, "f_x*f_z") not in by
    assert not any(t.term in ("t", "temp", "f_x", "f_y", "f_z") for t in terms)
    # the same quantity on another channel is
    assert (0, "f_y^2") in by and (2, "abs(f_x)") in by and (0, "f_x^3") in by
    t = next(t for t in terms if t.term == "f_y^2" and t.channel == 0)
    np.testing.assert_allclose(t.values, (ev.f_m_s2[:, 1] / G0_M_S2) ** 2)
    assert t.unit == "g^2" and t.degree == 2


def test_term_name_and_unit_group_powers() -> None:
    from bench.diagnosis.library import Base

    fx, fz, tmp = Base("f_x", "g", 0, "f"), Base("f_z", "g", 2, "f"), Base("temp", "°C", -1, "temp")
    assert term_name((fx, fx, fz)) == "f_x^2*f_z" and term_unit((fx, fx, fz)) == "g^3"
    assert term_name((fx, tmp)) == "f_x*temp" and term_unit((fx, tmp)) == "g·°C"


def test_on_six_axis_poses_a_cube_is_its_own_input_and_is_not_a_candidate() -> None:
    """On ±g along each axis f_x³ = f_x: the pose set cannot tell it from the first-order model."""
    six = DIRS[:6]
    six = np.vstack([six, six])  # 12 windows, the six poses twice
    terms, dropped = library_terms(_evidence(np.random.default_rng(1), dirs=six))
    assert not any(t.term == "f_x^3" for t in terms) and dropped > 0


def test_injected_alignment_creep_is_named_on_its_channel_within_its_sigma() -> None:
    """2e-7 V per g·s of f_z·t on ax (the mount creeping; ~8 sigma of its estimate): discovered
    on ax, coefficient within 3 sigma, no catalogue claim, the final model fits."""
    ev0 = _evidence(np.random.default_rng(3))
    c = 2e-7
    extra = np.zeros_like(ev0.y)
    extra[:, 0] = c * (ev0.f_m_s2[:, 2] / G0_M_S2) * ev0.mid_s
    d = diagnose(_evidence(np.random.default_rng(3), extra))
    assert d.findings == ()
    assert [(x.channel, x.term) for x in d.discovered] == [("ax", "f_z*t")]
    x = d.discovered[0]
    assert abs(x.coefficient - c) < 3 * x.sigma and x.sigma < c / 5
    assert x.delta_bic < 0 and "drifts during the run" in x.physics and x.unit == "channel unit per g·s"
    assert d.unexplained is None and d.final.chi2_dof < 2
    doc = d.to_contract()
    assert doc["discovered"][0]["term"] == "f_z*t" and "unexplained" not in doc
    assert "DISCOVERED f_z*t on ax" in format_human(d)


def test_clean_synthetic_has_nothing_discovered_and_no_unexplained() -> None:
    for seed in range(4):
        d = diagnose(_evidence(np.random.default_rng(10 + seed)))
        assert d.findings == () and d.discovered == () and d.unexplained is None
        assert d.to_contract()["discovered"] == []


def test_one_channel_random_offsets_are_not_a_pose_error_and_are_unexplained() -> None:
    """Offsets on ax alone, different in every window (30 sigma rms): nothing the library holds,
    and a pose error would move two channels: no claim, and ``unexplained`` names ax."""
    rng = np.random.default_rng(5)
    ev0 = _evidence(rng)
    extra = np.zeros_like(ev0.y)
    extra[:, 0] = 30 * SIGMA * np.random.default_rng(6).standard_normal(ev0.m)
    d = diagnose(_evidence(np.random.default_rng(5), extra))
    assert "pose_error" not in [f.effect for f in d.findings]
    assert d.unexplained is not None and d.unexplained.where.startswith("ax")
    assert d.unexplained.channels["ax"] > 5 * max(d.unexplained.channels["ay"], d.unexplained.channels["az"])
    assert "UNEXPLAINED" in format_human(d) and "unexplained" in d.to_contract()


def test_pose_edf_is_the_trace_of_the_smoother_by_finite_differences() -> None:
    """edf = tr(∂(J p̂)/∂z): the BLUP offsets differentiated column by column."""
    ev = _evidence(np.random.default_rng(7))
    K = np.diag([0.0177, 0.0175, 0.0178])
    J = pose_response(ev, K)
    X = first_order_design(ev.f_m_s2)
    noise = NoiseParams(tau2=np.zeros(3), pose_var_rad2=(2 * SIGMA / (G * 0.0177)) ** 2)
    chk = pose_check(ev.V, ev.mid_s, noise, J, X, ev.y.reshape(-1))
    C = covariance(ev.V, ev.mid_s, noise, J)
    Ci = np.linalg.inv(C)
    n = ev.n_obs
    Gm = np.zeros((n, n))
    for w in range(ev.m):
        Gm[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = J[w] @ J[w].T

    def offsets(z: np.ndarray) -> np.ndarray:
        th = np.linalg.solve(X.T @ Ci @ X, X.T @ Ci @ z)
        return noise.pose_var_rad2 * Gm @ Ci @ (z - X @ th)

    z0 = ev.y.reshape(-1)
    base = offsets(z0)
    h = 1e-6
    trace = sum((offsets(z0 + h * np.eye(n)[k]) - base)[k] / h for k in range(n))
    assert chk.edf == pytest.approx(trace, rel=1e-5)
    assert 1.0 < chk.edf < 2 * ev.m


def test_channel_forms_mean_matches_monte_carlo() -> None:
    """E[q_i] = tr(D_i M) against 400 draws of z with covariance C (slow noise correlated in time)."""
    rng = np.random.default_rng(8)
    ev = _evidence(rng)
    noise = NoiseParams(tau2=np.array([4.0, 1.0, 2.0]) * SIGMA**2, corr_time_s=200.0)
    C = covariance(ev.V, ev.mid_s, noise)
    X = first_order_design(ev.f_m_s2)
    L = np.linalg.cholesky(C)
    qs = np.array([channel_forms(C, C, X, L @ rng.standard_normal(ev.n_obs))[0] for _ in range(400)])
    _, e, v = channel_forms(C, C, X, ev.y.reshape(-1))
    np.testing.assert_allclose(qs.mean(axis=0), e, atol=4 * np.sqrt(v / 400).max())
    np.testing.assert_allclose(qs.var(axis=0), v, rtol=0.35)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scale_temperature", "fixture_temperature", "mount_creep", "cross_square"])
def test_concealed_term_is_named_or_its_alike_twin(name: str) -> None:
    """Out-of-catalogue term at the study's size: named on its channel within 3 sigma of the
    truth (or, for f_y² on the 12-pose set, a term it cannot be told from, which lists it), and
    no catalogue effect claimed."""
    from bench.calibration.diagnose import diagnose_recording
    from benchmarks.library_cases import CASES, score

    case = CASES[name]
    d = diagnose_recording(case.recording(11))
    s = score(case, d)
    assert s.catalogue == (), s
    if s.named:
        assert abs(s.z) < 3.0, s
    else:
        ch = ("ax", "ay", "az")[case.channel]
        twin = [x for x in d.discovered if x.channel == ch and case.term in x.confounded_with]
        assert twin, s


CUBE_CLAIM_RATE = 0.19
"""Share of static-12 recordings with the concealed cube (``cubic`` of benchmarks/library_cases)
that claim a catalogue effect (always cross_coupling alone): 15 of 80 (seeds 200-279,
``python -m benchmarks.study_sampled_rates cube``, 95 % interval 11-29 %, docs/diagnose.md)."""
CUBE_UNNAMED_RATE = 0.09
"""Share of the same recordings with no catalogue claim where no term on ax is f_x^3 or lists it:
7 of 80 (95 % interval 4-17 %)."""
CUBE_OTHER_RATE = 0.045
"""Share with a catalogue claim other than cross_coupling alone: none of the 80, and 0.045 the
upper end of its 95 % interval."""
CUBE_SEEDS = range(1, 25)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_concealed_cube_is_not_taken_for_cross_coupling() -> None:
    """f_x³ on ax (``cubic`` of benchmarks/library_cases), seeds 1-24: on the 12-pose set it is
    the signature of f_x·|f_x| (|cos| = 1.00 beyond f_x), which cross_coupling's three products
    partly mimic. cross_coupling enters first; where the library then needs a term beside it
    on ax, the two compete head to head (``catalogue_swap.swap_step``) and the cube's twin wins.
    Each count over these 24 seeds (which the study does not use) may reach the 99.9 % point of
    Bin(24, rate), the rate measured by the study (the constants above): 11 recordings with
    cross_coupling, 7 with no claim and the cube unnamed, 5 with another claim. A true rate of
    50 % fails the first with probability 0.58, of 30 % the second with 0.44 and the third with 0.77."""
    from scipy.stats import binom

    from bench.calibration.diagnose import diagnose_recording
    from benchmarks.library_cases import CASES, score

    case = CASES["cubic"]
    claimed: list[int] = []
    unnamed: list[int] = []
    other: list[int] = []
    for seed in CUBE_SEEDS:
        d = diagnose_recording(case.recording(seed))
        s = score(case, d)
        if s.catalogue:
            (claimed if s.catalogue == ("cross_coupling",) else other).append(seed)
        elif not any(x.channel == "ax" and "f_x^3" in (x.term, *x.confounded_with) for x in d.discovered):
            unnamed.append(seed)
    n = len(CUBE_SEEDS)
    assert len(claimed) <= binom.ppf(0.999, n, CUBE_CLAIM_RATE), claimed
    assert len(unnamed) <= binom.ppf(0.999, n, CUBE_UNNAMED_RATE), unnamed
    assert len(other) <= binom.ppf(0.999, n, CUBE_OTHER_RATE), other


@pytest.mark.slow
def test_loose_connector_is_never_a_pose_error_and_mostly_unexplained_on_ax() -> None:
    """Random per-window offsets on ax (study seeds 100-105): never a pose error; ``unexplained``
    names ax in at least 3 of 6 (measured 6 of 6 with a winning excess carried into the
    selection's noise; 3 of 6 before the head to head, docs/diagnose.md)."""
    from bench.calibration.diagnose import diagnose_recording
    from benchmarks.library_cases import CASES

    flagged = 0
    for seed in range(100, 106):
        d = diagnose_recording(CASES["loose_connector"].recording(seed))
        assert "pose_error" not in [f.effect for f in d.findings], seed
        flagged += d.unexplained is not None and d.unexplained.where.startswith("ax")
    assert flagged >= 3


@pytest.mark.slow
def test_one_channel_delay_on_a_moving_recording_is_discovered() -> None:
    """ax delayed 5 ms behind ay, az (a per-channel timing defect the catalogue's common
    time_skew cannot express): the moving library names fdot_x on ax, a delay of ax alone, and
    the final model fits. The delay is the simulator's own (``time_skew`` moves the signal, not
    the noise) taken for ax only: interpolating the recorded samples would average neighbouring
    noise samples and lower ax's second-difference noise 3-fold, a mismatch of its own.
    Coefficient and sigma: ``test_diagnosis_library_motion``."""
    from dataclasses import replace

    from bench.calibration.diagnose import diagnose_recording
    from tests.support.diagnose_dynamic_cases import moving_recording

    rec = moving_recording({}, 7)
    raw = rec.accel_raw.copy()
    raw[:, 0] = moving_recording({"time_skew": {"delay_s": 0.005}}, 7).accel_raw[:, 0]
    d = diagnose_recording(replace(rec, accel_raw=raw))
    assert [(x.channel, x.term) for x in d.discovered] == [("ax", "fdot_x")]
    assert d.unexplained is None
    assert diagnose_recording(rec).unexplained is None


@pytest.mark.slow
@pytest.mark.timeout(2400)
def test_false_findings_on_two_hundred_clean_recordings_count_discovered_terms() -> None:
    """200 clean static-12 recordings, each count within a binomial margin of its nominal rate
    (the margin, not the count measured, is the bound): a discovered term at the library's level,
    p_L = ``library_share``·``false_alarm`` = 0.001, and any claim (finding or discovered term)
    at p0 = ``clean_finding_rate`` = 0.012 (tests/support/diagnose_cases.py); n = 200, and each
    count may reach the 99.9 % point of Bin(n, p): 3 for p_L, 8 for p0 at the defaults (power:
    a true claim rate of 5 % fails it with probability 0.67). Measured: no discovered term; 2 claims,
    settling on 1036 and 1176 at p = 0.0009, the only two of 1000 clean recordings below its
    0.001 gate (docs/diagnose.md)."""
    from scipy.stats import binom

    from bench.calibration.diagnose import diagnose_recording
    from bench.diagnosis.thresholds import Thresholds
    from tests.support.diagnose_cases import clean_finding_rate, static_recording

    th, n = Thresholds(), 200
    bound_discovered = binom.ppf(0.999, n, th.library_share * th.false_alarm)
    bound_false = binom.ppf(0.999, n, clean_finding_rate(th))
    false, discovered = {}, {}
    for seed in range(1000, 1000 + n):
        d = diagnose_recording(static_recording({}, seed=seed))
        claims = [f.effect for f in d.findings] + [f"{x.term}[{x.channel}]" for x in d.discovered]
        if claims:
            false[seed] = claims
        if d.discovered:
            discovered[seed] = claims
    assert len(discovered) <= bound_discovered, (bound_discovered, discovered)
    assert len(false) <= bound_false, (bound_false, false)


@pytest.mark.parametrize(
    ("tau2", "corr_time_s", "sort"),
    [
        ((2e-6, 5e-7, 1e-6), 200.0, True),
        ((2e-6, 0.0, 1e-6), 50.0, False),  # windows out of time order, one channel without wander
        ((2e-6, 5e-7, 1e-6), 0.0, False),  # wander independent between windows
    ],
)
def test_gls_channel_forms_equal_the_dense_formulas(
    tau2: tuple[float, float, float], corr_time_s: float, sort: bool
) -> None:
    """The O(m) channel forms (residual from the factor, traces through the exponential kernel's
    recursions) agree with the general n × n ones (M = R C Rᵀ) when the model is fitted under its
    own covariance."""
    from bench.diagnosis.catch_all import channel_forms, gls_channel_forms
    from bench.diagnosis.likelihood import NoiseParams, window_covariance

    rng = np.random.default_rng(3)
    m = 20
    A = rng.normal(size=(m, 3, 3)) * 1e-3
    V = np.einsum("wij,wkj->wik", A, A) + 1e-6 * np.eye(3)
    mid_s = rng.uniform(0.0, 600.0, m)
    mid_s = np.sort(mid_s) if sort else mid_s
    noise = NoiseParams(tau2=np.array(tau2), corr_time_s=corr_time_s, pose_var_rad2=0.0)
    cov = window_covariance(V, mid_s, noise)
    X = rng.normal(size=(3 * m, 12))
    z = rng.normal(size=3 * m) * 1e-3
    C = cov.dense()
    for fast, dense in zip(gls_channel_forms(cov, X, z), channel_forms(C, C, X, z), strict=True):
        np.testing.assert_allclose(fast, dense, rtol=1e-8)


def test_exponential_kernel_product_is_the_dense_kernel() -> None:
    """P Y by the forward and backward recursions against exp(−|Δt|/T) formed densely."""
    from bench.diagnosis.catch_all import exponential_kernel_product

    rng = np.random.default_rng(4)
    t = rng.uniform(0.0, 100.0, 30)
    Y = rng.normal(size=(30, 4))
    P = np.exp(-np.abs(t[:, None] - t[None, :]) / 7.0)
    np.testing.assert_allclose(exponential_kernel_product(t, 7.0, Y), P @ Y, rtol=1e-12)
    np.testing.assert_allclose(exponential_kernel_product(t, 0.0, Y), Y)
