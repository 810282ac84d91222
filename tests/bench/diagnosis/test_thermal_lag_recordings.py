"""``thermal_lag`` on simulated static-12 recordings (``tests/support/thermal_lag_cases.py``):
the lag named with its time constant, a plain coefficient left to ``temperature_bias``, the text
and the JSON saying the same, and (slow) the rates of ``benchmarks/study_thermal_lag.py`` against
binomial margins of their design rates."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.stats import binom, chi2

from bench.calibration.diagnose import diagnose_recording, recording_evidence
from bench.diagnosis.effects import first_order_design
from bench.diagnosis.effects.thermal_lag import THERMAL_LAG
from bench.diagnosis.profiled import arc_length, davies_gate, projected_gram
from bench.diagnosis.thresholds import THRESHOLDS
from bench.estimation.slow_noise import NoiseParams
from tests.support.thermal_lag_cases import lag_finding, lag_recording, named, other_claims, plain_named


def test_a_lag_is_named_with_its_time_constant_and_the_text_says_what_the_json_does() -> None:
    d = diagnose_recording(lag_recording(1e-2, 60.0, 100))
    got = lag_finding(d)
    assert got is not None and named(d, 1e-2)
    tc, s_tc, tau, s_tau = got
    assert abs(tau - 60.0) < 3.0 * s_tau and 0 < s_tau < 60.0
    assert other_claims(d, "thermal_lag") == []
    f = next(f for f in d.findings if f.effect == "thermal_lag")
    out = d.to_contract()["findings"][0]
    assert out["effect"] == "thermal_lag" and out["parameters"]["tau_s"][1] == tau
    # the sentence carries the JSON's numbers at its precision, on the channel the JSON names
    m = re.search(r"y channel (\S+) ± (\S+) m/s²/°C through a lag of τ = (\S+) ± (\S+) s", f.summary)
    assert m is not None
    for text, value in zip(m.groups(), (tc, s_tc, tau, s_tau), strict=True):
        assert abs(float(text) - value) <= 0.051 * abs(value)
    assert out["parameters"]["tc_m_s2_per_c"][0] == out["parameters"]["tc_m_s2_per_c"][2] == 0.0


@pytest.mark.slow
def test_a_plain_coefficient_stays_temperature_bias() -> None:
    d = diagnose_recording(lag_recording(1e-2, 0.0, 300))
    assert plain_named(d, 1e-2) and lag_finding(d) is None
    assert "thermal_lag" not in {e for f in d.findings for e in f.confounded_with}


def test_davies_gate_on_the_lag_family_of_a_recording() -> None:
    # under no effect and known noise, a·Py over the grid is Gaussian with the projected Gram G
    # of the lag's columns (``profiled.projected_gram``): the maximum over τ of (a·Py)²/aᵀPa
    # passes Davies' gate at α at a rate of at most α, and at least half of it (not a
    # Bonferroni over the grid's values, which would be far stricter)
    ev = recording_evidence(lag_recording(0.0, 0.0, 1000))
    K = np.eye(3)
    fam = THERMAL_LAG.candidates(ev)[1].family
    assert fam is not None
    A = np.hstack([fam.column(ev, K, v) for v in fam.grid])
    noise = NoiseParams(tau2=np.zeros(3))
    _, G, _ = projected_gram(ev, first_order_design(ev.f_m_s2), A, noise, K, None)
    length = arc_length(G, np.ones(len(fam.grid), bool))
    assert 0.5 < length < math.pi
    alpha, draws = 0.05, 40_000
    w, U = np.linalg.eigh(G)
    z = np.random.default_rng(7).standard_normal((draws, w.size)) @ (U * np.sqrt(np.clip(w, 0.0, None))).T
    lr = np.max(z**2 / np.diag(G), axis=1)
    rate = float(np.mean(lr > davies_gate(alpha, length)))
    se = math.sqrt(alpha * (1 - alpha) / draws)
    assert 0.5 * alpha < rate < alpha + 4 * se
    assert float(np.mean(lr > chi2.isf(alpha / len(fam.grid), 1))) < 0.6 * rate


# Design rates of the slow tests, with bounds at the binomial 99.9 % points: a lag of 3e-2
# m/s²/°C (its Δχ² far above its gate, its sigmas honest or conservative) named at 0.95 or more;
# a thermal_lag claimed on a clean recording, or for a plain coefficient, at no more than
# ``false_alarm`` (its share of the step's budget under Davies' bound; the lag-or-none test).


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_large_lag_is_named() -> None:
    n = 6
    named_n = sum(
        named(diagnose_recording(lag_recording(3e-2, tau, s)), 3e-2)
        for tau in (30.0, 120.0)
        for s in range(100, 100 + n)
    )
    assert named_n >= binom.ppf(0.001, 2 * n, 0.95)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_no_lag_on_clean_recordings() -> None:
    m = 40
    false_lag = sum(
        lag_finding(diagnose_recording(lag_recording(0.0, 0.0, s))) is not None for s in range(1000, 1000 + m)
    )
    assert false_lag <= binom.ppf(0.999, m, THRESHOLDS.false_alarm)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_plain_coefficient_is_not_taken_for_a_lag() -> None:
    p = 20
    mis = sum(
        lag_finding(diagnose_recording(lag_recording(1e-2, 0.0, s))) is not None for s in range(300, 300 + p)
    )
    assert mis <= binom.ppf(0.999, p, THRESHOLDS.false_alarm)
