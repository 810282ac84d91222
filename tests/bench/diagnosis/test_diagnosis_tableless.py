"""Recordings without a table: no table effect is claimed, and orientation-free χ²/dof counts
the scalar fit's degrees of freedom (m − 9), not the stacked 3m − 12."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bench.diagnosis import NO_TABLE_REASON, StaticEvidence, diagnose
from bench.diagnosis.effects import NEEDS_TABLE, first_order_design, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.effects.settling import settling_test
from bench.diagnosis.likelihood import NoiseParams
from bench.diagnosis.refit import evaluate, residual_dof
from bench.estimation.scalar_fit import fit_scalar

RATE_HZ = 100.0
G = 9.81
K_TRUE = np.array([[0.0177, 1e-5, -2e-5], [0.0, 0.0175, 3e-5], [0.0, 0.0, 0.0178]])
B_TRUE = np.array([1.5, 1.49, 1.51])
_DIRS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
     [1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, 1, 0], [-1, 0, -1], [0, -1, 1],
     [1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1], [1, 0, -1], [0, 1, -1]],
    dtype=float,
)  # fmt: skip
F_TRUE = G * _DIRS / np.linalg.norm(_DIRS, axis=1, keepdims=True)


def _orientation_free(rng: np.random.Generator, m: int, sigma: float) -> StaticEvidence:
    """m windows in random directions, white noise of known sigma; f from the scalar fit, as
    ``diagnose_recording`` does without a table or labels."""
    u = rng.normal(size=(m, 3))
    f = G * u / np.linalg.norm(u, axis=1, keepdims=True)
    y = B_TRUE + f @ K_TRUE.T + rng.normal(0.0, sigma, (m, 3))
    V = np.broadcast_to(np.eye(3) * sigma**2, (m, 3, 3)).copy()
    sf = fit_scalar(y, V, G)
    d = np.linalg.solve(sf.L, (y - sf.bias).T).T
    f_hat = G * d / np.linalg.norm(d, axis=1, keepdims=True)
    return StaticEvidence(
        y=y,
        V=V,
        f_m_s2=f_hat,
        mid_s=np.arange(m) * 40.0,
        labels=tuple(f"w{i}" for i in range(m)),
        g_local_m_s2=G,
        orientation_known=False,
    )


def test_orientation_free_dof_is_the_scalar_fits() -> None:
    ev = _orientation_free(np.random.default_rng(0), 20, 1e-5)
    assert residual_dof(ev, 12) == 20 - 9
    assert residual_dof(ev, 15) == 20 - 12  # three effect coefficients cost three dof
    known = StaticEvidence(y=ev.y, V=ev.V, f_m_s2=ev.f_m_s2, mid_s=ev.mid_s, labels=ev.labels, g_local_m_s2=G)
    assert residual_dof(known, 12) == 3 * 20 - 12


def test_orientation_free_chi2_dof_averages_one_under_the_true_noise() -> None:
    """χ² of the first-order model under the known noise (no slow noise, each window's
    direction free by 0.1 rad as in ``diagnose``): its mean over recordings is 1 with the
    scalar fit's m − 9 dof; with 3m − 12 it would be (m − 9)/(3m − 12) = 0.25 here."""
    m, n_rec = 24, 120
    rng = np.random.default_rng(11)
    noise = NoiseParams(tau2=np.zeros(3), corr_time_s=0.0)
    ratios = []
    for _ in range(n_rec):
        ev = _orientation_free(rng, m, 2e-5)
        X0 = first_order_design(ev.f_m_s2)
        K0 = np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12].reshape(3, 3)
        J = pose_response(ev, K0)
        fixed = 0.1**2 * np.einsum("wik,wjk->wij", J, J)
        ratios.append(evaluate(ev, [], False, noise, K0, fixed).chi2_dof)
    mean = float(np.mean(ratios))
    # χ²_{m−9}/(m−9): sd sqrt(2/15) per recording, over 120 recordings 0.033
    assert abs(mean - 1.0) < 4 * math.sqrt(2.0 / (m - 9) / n_rec), mean


def _ringing_windows(rng: np.random.Generator) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """18 hand-placed poses of 30 s, each starting with a decaying 8 Hz ring."""
    n = round(30.0 * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    ring = 3e-4 * np.exp(-t / 2.0) * np.sin(2 * math.pi * 8.0 * t)
    wins = []
    for f in F_TRUE:
        x = B_TRUE + K_TRUE @ f + rng.normal(0.0, 1e-4, (n, 3)) + ring[:, None] * np.array([1.0, 0.5, 0.2])
        wins.append(x)
    return tuple(wins), F_TRUE


def test_no_table_effect_is_claimed_without_a_table() -> None:
    wins, f = _ringing_windows(np.random.default_rng(3))
    # the ring is there: the settling test alone finds it at 8 Hz
    st = settling_test(wins, RATE_HZ)
    assert st.p_value < 1e-6 and st.frequency_hz == 8.0
    y = np.array([w.mean(axis=0) for w in wins])
    V = np.array([np.cov(w.T) / w.shape[0] for w in wins])
    m = y.shape[0]
    ev = StaticEvidence(
        y=y,
        V=V,
        f_m_s2=f,
        mid_s=np.arange(m) * 40.0,
        labels=tuple(f"pose{i}" for i in range(m)),
        g_local_m_s2=G,
        window_samples=wins,
        sample_rate_hz=RATE_HZ,
    )
    assert not ev.has_table
    d = diagnose(ev)
    assert not {x.effect for x in d.findings} & NEEDS_TABLE
    for effect in NEEDS_TABLE:  # one reason for all, no words about a table standing still
        assert d.unobservable[effect] == NO_TABLE_REASON
    assert "table" not in " ".join(x.summary for x in d.findings)


def test_orientation_free_diagnosis_without_redundancy_is_refused() -> None:
    ev = _orientation_free(np.random.default_rng(5), 9, 1e-5)
    with pytest.raises(
        ValueError, match=r"orientation-free diagnosis needs at least 10 static windows.*got 9"
    ):
        diagnose(ev)


def _with_samples(rng: np.random.Generator, ev: StaticEvidence, y: FloatArray) -> StaticEvidence:
    """``ev`` with window means ``y``, f from their scalar fit, and 400 white samples per window
    around each mean (their half-window differences bound the slow wander)."""
    sf = fit_scalar(y, ev.V, G)
    d = np.linalg.solve(sf.L, (y - sf.bias).T).T
    samples = []
    for mean in y:
        s = rng.normal(0.0, 2e-4, (400, 3))
        samples.append(s - s.mean(axis=0) + mean)
    return replace(
        ev,
        y=y,
        f_m_s2=G * d / np.linalg.norm(d, axis=1, keepdims=True),
        window_samples=samples,
        sample_rate_hz=RATE_HZ,
    )


def test_orientation_free_clean_fit_is_not_unexplained_and_a_magnitude_misfit_is() -> None:
    """Orientation-free evidence tests only each reading's magnitude, against the scalar fit's
    m − 9 dof: a clean recording is not flagged (its per-channel χ² is far below the
    orientation-inflated expectation by design), and an unmodelled magnitude error (each
    reading scaled by 1 ± 2e-3 with a sign drawn at random per window, the same on every
    channel: 0.35 mV on 0.17 V against 10 µV noise; no term of the pose follows it) is flagged
    on the magnitude, with no channel named (the misfit is common to the channels)."""
    rng = np.random.default_rng(7)
    ev = _orientation_free(rng, 24, 1e-5)
    assert diagnose(_with_samples(rng, ev, ev.y)).unexplained is None
    u = np.linalg.solve(K_TRUE, (ev.y - B_TRUE).T).T
    sign = np.random.default_rng(107).choice([-1.0, 1.0], ev.m)
    bent = B_TRUE + (u * (1.0 + 2e-3 * sign)[:, None]) @ K_TRUE.T
    un = diagnose(_with_samples(rng, ev, bent)).unexplained
    assert un is not None and un.channels == {} and un.where.startswith("the magnitude")
    assert un.channel is None
