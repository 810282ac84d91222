"""Each stage of the window-means pipeline against its one rule, on constructed evidence whose
answer is known: 18 window means in known directions, white noise of known sigma, no table."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.diagnosis.check_stages import out_of_sample_referee, prune_redundant
from bench.diagnosis.effects import NEEDS_TABLE, Candidate, first_order_design
from bench.diagnosis.effects.base import FloatArray, channel_column
from bench.diagnosis.effects.sensor import NONLINEARITY
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import Path
from bench.diagnosis.library import EFFECT
from bench.diagnosis.model_state import ModelState, Step, fit_model
from bench.diagnosis.report_stages import (
    bench_lines,
    refit_sequence,
    settling,
    unexplained_stage,
    within_window,
)
from bench.diagnosis.screen_stages import (
    NO_TABLE_REASON,
    encoder_quantisation,
    library_search,
    orientation_prior,
    screen_catalogue,
)
from bench.diagnosis.selection import select
from bench.diagnosis.selection_stages import forward_selection, resumed
from bench.diagnosis.stages import ORIENTATION_FREE, STATIC, STATIC_NO_LIBRARY, pipeline_for
from bench.diagnosis.thresholds import THRESHOLDS
from bench.diagnosis.window_state import WindowState
from tests.bench.diagnosis.test_diagnosis_tableless import B_TRUE, K_TRUE, RATE_HZ, G
from tests.bench.diagnosis.test_diagnosis_tableless import F_TRUE as F
from tests.bench.diagnosis.test_pose_quantisation import _evidence as table_evidence

SIGMA = 1e-5
M = F.shape[0]


def _evidence(seed: int, extra: FloatArray | None = None, **kw: object) -> StaticEvidence:
    """The 18 windows, white noise SIGMA; ``extra`` (3m,) added to the stacked means."""
    y = B_TRUE + F @ K_TRUE.T + np.random.default_rng(seed).normal(0.0, SIGMA, (M, 3))
    if extra is not None:
        y = y + extra.reshape(M, 3)
    V = np.broadcast_to(np.eye(3) * SIGMA**2, (M, 3, 3)).copy()
    return StaticEvidence(
        y=y, V=V, f_m_s2=F, mid_s=np.arange(M) * 40.0, labels=tuple(f"w{i}" for i in range(M)),
        g_local_m_s2=G, **kw,  # type: ignore[arg-type]
    )  # fmt: skip


def _quadratic_z(k2_per_g: float) -> FloatArray:
    ev = _evidence(0)
    return k2_per_g * NONLINEARITY.candidates(ev)[2].columns(ev, K_TRUE)[:, 0]


def _column(name: str, ch: int, values: FloatArray) -> Candidate:
    def cols(e: StaticEvidence, K: FloatArray) -> FloatArray:
        return channel_column(e, ch, values)

    return Candidate(name, f"{name}[{ch}]", (ch,), cols, (name,), lambda t, c, K: ({}, {}))


def _model(ev: StaticEvidence, cands: list[Candidate]) -> ModelState:
    theta = np.linalg.lstsq(first_order_design(F), ev.y.reshape(-1), rcond=None)[0]
    K0 = np.asarray(theta[3:12], dtype=np.float64).reshape(3, 3)
    noise, fit, _ = fit_model(ev, cands, False, K0, None, iterations=2)
    steps = [Step(c.label, c.effect, 0.0, 0.0, len(c.names)) for c in cands]
    return ModelState(candidates=list(cands), noise=noise, fit=fit, steps=steps)


def _selected(ev: StaticEvidence, st: WindowState, cands: list[Candidate]) -> WindowState:
    """``st`` after a selection whose path admitted ``cands`` one by one (each model refitted);
    the path's groups are those of the selection on ``st``'s catalogue pool, without a library."""
    sel = select(ev, list(st.pool), pose_allowed=False)
    states = tuple(_model(ev, cands[:k]) for k in range(len(cands) + 1))
    sel = replace(sel, path=Path(states, tuple({} for _ in states)))
    return replace(st, selection=sel, model=sel.model)


def test_screen_sets_the_tables_physics_aside_without_a_table() -> None:
    st, notes = screen_catalogue(_evidence(1), WindowState(), THRESHOLDS)
    assert notes == {}
    assert set(st.unobservable) >= NEEDS_TABLE
    assert all(st.unobservable[e] == NO_TABLE_REASON for e in NEEDS_TABLE)
    assert not {c.effect for c in st.pool} & NEEDS_TABLE
    # three channels each: the quadratic, the asymmetry, the three products, the drift
    assert {c.effect for c in st.pool} >= {"nonlinearity_quadratic", "scale_asymmetry", "cross_coupling"}
    assert st.pose_ok and not st.settle_ok  # the pose error is a variance, settling needs a table


def test_orientation_prior_is_rank_two_and_scales_with_its_sigma() -> None:
    ev = _evidence(1)
    st, _ = orientation_prior(ev, WindowState(), THRESHOLDS)
    assert st.fixed is None  # orientation known: no prior
    free = replace(ev, orientation_known=False)
    a, _ = orientation_prior(free, WindowState(), THRESHOLDS)
    b, _ = orientation_prior(
        free, WindowState(), replace(THRESHOLDS, free_orientation_rad=2 * THRESHOLDS.free_orientation_rad)
    )
    assert a.fixed is not None and b.fixed is not None and a.fixed.shape == (M, 3, 3)
    np.testing.assert_allclose(b.fixed, 4.0 * a.fixed, rtol=1e-12)
    # two free angles per window (about the axes perpendicular to gravity): rank 2
    s = np.linalg.svd(a.fixed, compute_uv=False)
    assert np.all(s[:, 2] < 1e-9 * s[:, 0]) and np.all(s[:, 1] > 1e-3 * s[:, 0])


def test_encoder_step_adds_its_scatter_to_the_fixed_covariance() -> None:
    st, _ = encoder_quantisation(_evidence(1), WindowState(), THRESHOLDS)
    assert st.fixed is None  # no table, no declared step
    one, _ = encoder_quantisation(table_evidence(1e-3, K_TRUE), WindowState(), THRESHOLDS)
    two, _ = encoder_quantisation(table_evidence(2e-3, K_TRUE), WindowState(), THRESHOLDS)
    assert one.fixed is not None and two.fixed is not None
    np.testing.assert_allclose(two.fixed, 4.0 * one.fixed, rtol=1e-9)  # step² / 12
    prior = np.broadcast_to(np.eye(3), one.fixed.shape).copy()
    both, _ = encoder_quantisation(table_evidence(1e-3, K_TRUE), WindowState(fixed=prior), THRESHOLDS)
    assert both.fixed is not None
    np.testing.assert_allclose(both.fixed, prior + one.fixed, rtol=1e-12)


def test_library_on_known_and_orientation_free_evidence() -> None:
    """The same pose set gives the same candidates whether its orientations are known or read
    from the readings (only the magnitude of a term's signature is evidence then)."""
    ev = _evidence(1)
    st, _ = library_search(ev, WindowState(), THRESHOLDS)
    assert st.lib_terms and all(k.startswith(EFFECT + ":") for k in st.lib_terms)
    free, _ = library_search(replace(ev, orientation_known=False), WindowState(), THRESHOLDS)
    assert set(free.lib_terms) == set(st.lib_terms) and EFFECT not in free.unobservable


def test_forward_selection_admits_a_strong_effect_and_nothing_on_noise() -> None:
    # 1e-3/g on z: K_zz g 1e-3 = 1.7e-4 at ±z, 17 sigma
    ev = _evidence(2, _quadratic_z(1e-3))
    st, _ = screen_catalogue(ev, WindowState(), THRESHOLDS)
    st, _ = forward_selection(ev, st, THRESHOLDS)
    assert st.model is not None and [c.label for c in st.model.candidates] == ["nonlinearity_quadratic[z]"]
    clean = _evidence(3)
    st, _ = screen_catalogue(clean, WindowState(), THRESHOLDS)
    st, _ = forward_selection(clean, st, THRESHOLDS)
    assert st.model is not None and st.model.candidates == [] and not st.model.pose


def test_prune_drops_a_catalogue_effect_a_library_term_made_redundant() -> None:
    # truth: a cube on ax (odd), 30 sigma; the model also holds the x quadratic (even, truth 0)
    cube = F[:, 0] ** 3 / G**3
    extra = np.zeros(3 * M)
    extra[0::3] = 30 * SIGMA * cube
    ev = _evidence(4, extra)
    st, _ = screen_catalogue(ev, WindowState(), THRESHOLDS)
    quad_x = NONLINEARITY.candidates(ev)[0]
    out, notes = prune_redundant(
        ev, _selected(ev, st, [quad_x, _column(f"{EFFECT}:cube", 0, cube)]), THRESHOLDS
    )
    assert out.excluded == {"nonlinearity_quadratic"}
    assert "dropped" in notes["nonlinearity_quadratic"]
    assert out.model is not None and "nonlinearity_quadratic" not in {c.effect for c in out.model.candidates}
    # without a library term in the model there is nothing to prune
    same, none = prune_redundant(ev, _selected(ev, st, [quad_x]), THRESHOLDS)
    assert none == {} and same.excluded == frozenset()


def test_a_pruned_effect_resumes_the_selection_from_the_step_before_it_entered() -> None:
    # truth: a ramp on ay (30 sigma) and a cube on ax (30 sigma); the path admitted the ramp,
    # then the x quadratic (truth 0), then the cube
    ramp, cube = np.linspace(-1.0, 1.0, M), F[:, 0] ** 3 / G**3
    extra = np.zeros((M, 3))
    extra[:, 0], extra[:, 1] = 30 * SIGMA * cube, 30 * SIGMA * ramp
    ev = _evidence(4, extra.reshape(-1))
    st, _ = screen_catalogue(ev, WindowState(), THRESHOLDS)
    ramp_y, quad_x = _column("ramp", 1, ramp), NONLINEARITY.candidates(ev)[0]
    before = _selected(ev, st, [ramp_y, quad_x, _column(f"{EFFECT}:cube", 0, cube)])
    out, _ = prune_redundant(ev, before, THRESHOLDS)
    assert before.selection is not None and out.selection is not None and out.model is not None
    # the step before the quadratic entered stands (its fit kept, not fitted again)
    now, then = out.selection.path.states, before.selection.path.states
    assert now[0] is then[0] and now[1].fit is then[1].fit
    assert out.model.candidates[0] is ramp_y
    assert "nonlinearity_quadratic" in out.model.excluded
    assert "nonlinearity_quadratic" not in {c.effect for c in out.model.candidates}
    # the path it left is unchanged (the states are not changed in place)
    assert [c.label for c in before.selection.path.last.candidates] == [
        "ramp[1]", "nonlinearity_quadratic[x]", f"{EFFECT}:cube[0]"
    ]  # fmt: skip


def test_referee_refuses_a_column_that_does_not_predict_a_left_out_window() -> None:
    ev = _evidence(5, _quadratic_z(1e-3))
    st, _ = screen_catalogue(ev, WindowState(), THRESHOLDS)
    noise_col = np.random.default_rng(6).normal(size=M)  # truth 0: it only follows the noise
    quad_z = NONLINEARITY.candidates(ev)[2]
    out, notes = out_of_sample_referee(
        ev, _selected(ev, st, [quad_z, _column("noise_column", 0, noise_col)]), THRESHOLDS
    )
    assert out.excluded == {"noise_column"}
    assert "left-out window" in notes["noise_column"]
    # the selection resumed without it from the step before it entered: the true effect alone
    assert out.model is not None and [c.effect for c in out.model.candidates] == ["nonlinearity_quadratic"]
    assert out.selection is not None and out.selection.path.steps == 1


def test_within_window_leaves_a_model_without_library_terms_alone() -> None:
    ev = _evidence(1)
    model = _model(ev, [])
    st, _ = within_window(ev, WindowState(model=model), THRESHOLDS)
    assert st.ev_final is ev and st.model is model


def test_refit_sequence_adds_the_effects_in_the_order_they_entered() -> None:
    ev = _evidence(2, _quadratic_z(1e-3))
    quad_z = NONLINEARITY.candidates(ev)[2]
    st, _ = refit_sequence(ev, WindowState(model=_model(ev, [quad_z]), ev_final=ev), THRESHOLDS)
    assert st.order == ("nonlinearity_quadratic",)
    assert [s.effects for s in st.seq] == [(), ("nonlinearity_quadratic",)]
    # 17 sigma left out of the first model, in the second: chi2/dof near 1
    assert st.seq[0].chi2_dof > 10 and st.seq[1].chi2_dof < 2


def _samples(
    rng: np.random.Generator, line_amp: float, ring_amp: float
) -> tuple[tuple[FloatArray, ...], tuple[FloatArray, ...]]:
    """Per window 30 s at 100 Hz, unit white noise, a 2.5 Hz line on ax (phase kept across
    windows) and a 7 Hz ring decaying over 2 s after each window's start."""
    n = round(30.0 * RATE_HZ)
    tt, ys = [], []
    for w in range(M):
        t = 40.0 * w + np.arange(n) / RATE_HZ
        y = rng.standard_normal((n, 3))
        y[:, 0] += line_amp * np.sin(2 * np.pi * 2.5 * t + 0.3)
        ring = ring_amp * np.exp(-(t - t[0]) / 2.0) * np.sin(2 * np.pi * 7.0 * (t - t[0]))
        y += ring[:, None] * np.array([1.0, 0.5, 0.2])
        tt.append(t)
        ys.append(y)
    return tuple(tt), tuple(ys)


def test_bench_lines_finds_a_line_at_its_frequency() -> None:
    t, y = _samples(np.random.default_rng(7), 0.3, 0.0)
    ev = _evidence(1, window_samples=y, window_t_s=t, sample_rate_hz=RATE_HZ)
    st, _ = bench_lines(ev, WindowState(), THRESHOLDS)
    assert len(st.lines) == 1 and st.lines[0].channels == (0,)
    assert abs(st.lines[0].frequency_hz - 2.5) < 3 * st.lines[0].frequency_sigma_hz
    # the samples kept for the window tests are without it
    assert st.line_free is not None
    before = np.abs(np.fft.rfft(y[0][:, 0]))[75]  # 2.5 Hz bin of 3000 samples at 100 Hz
    after = np.abs(np.fft.rfft(st.line_free[0][:, 0]))[75]
    # the line's bin: A n / 2 = 450 with it; unit white noise alone: Rayleigh of scale sqrt(n / 2)
    assert before > 6 * np.sqrt(3000) and after < 3 * np.sqrt(3000)


def test_settling_claims_a_ring_and_not_plain_noise() -> None:
    ev0 = _evidence(1)
    base, _ = refit_sequence(ev0, WindowState(model=_model(ev0, []), ev_final=ev0), THRESHOLDS)
    for ring, claimed in ((3.0, True), (0.0, False)):
        _, y = _samples(np.random.default_rng(8), 0.0, ring)
        ev = _evidence(1, window_samples=y, sample_rate_hz=RATE_HZ)
        st, _ = settling(ev, replace(base, settle_ok=True, line_free=y), THRESHOLDS)
        assert bool(st.extra) == claimed
        if claimed:
            assert st.extra[0].effect == "settling"
            assert abs(float(st.extra[0].parameters["frequency_hz"]) - 7.0) < 0.5
    # no window test where the screen did not allow it
    st, _ = settling(ev0, base, THRESHOLDS)
    assert st.extra == ()


def test_unexplained_fires_on_a_misfit_left_out_and_not_on_noise() -> None:
    for extra, fires in ((_quadratic_z(1e-3), True), (None, False)):
        ev = _evidence(9, extra)
        st, _ = refit_sequence(ev, WindowState(model=_model(ev, []), ev_final=ev), THRESHOLDS)
        st, _ = unexplained_stage(ev, st, THRESHOLDS)
        assert (st.left is not None) == fires


def test_pipelines_share_their_stage_functions() -> None:
    ev = _evidence(1)
    assert pipeline_for(ev) is STATIC
    assert pipeline_for(ev, use_library=False) is STATIC_NO_LIBRARY
    assert pipeline_for(replace(ev, orientation_known=False)) is ORIENTATION_FREE
    assert set(STATIC_NO_LIBRARY.stages) <= set(STATIC.stages)
    assert set(ORIENTATION_FREE.stages) == set(STATIC.stages) | {orientation_prior}
    assert STATIC.stage_names[:4] == (
        "screen_catalogue",
        "encoder_quantisation",
        "library_search",
        "forward_selection",
    )


def test_a_run_keeps_each_stages_notes_in_order() -> None:
    ev = _evidence(2, _quadratic_z(1e-3))
    st, trace = STATIC.run(ev, WindowState(), THRESHOLDS)
    assert trace.names == STATIC.stage_names
    assert st.order == ("nonlinearity_quadratic",)
    for _, notes in trace.stages:
        assert all(st.notes.get(k) is not None for k in notes)


def test_an_effect_searched_beside_the_library_stays_out_once_a_check_took_it_out() -> None:
    # truth: z² on az, 30 sigma; the only candidate that can take it is searched with the library
    # (as hysteresis is, ``effects.WITH_LIBRARY``), the catalogue pool is empty
    square = F[:, 2] ** 2 / G**2
    extra = np.zeros((M, 3))
    extra[:, 2] = 30 * SIGMA * square
    ev = _evidence(7, extra.reshape(-1))
    beside = _column("beside", 2, square)
    sel = select(ev, [], pose_allowed=False, library=[beside])
    assert [c.effect for c in sel.model.candidates] == ["beside"]
    # a check takes it out: the resumed selection does not take it back
    out = sel.without(["beside"])
    assert "beside" in out.model.excluded
    assert "beside" not in {c.effect for c in out.model.candidates}


def test_an_effect_taken_out_stays_out_when_a_later_check_resumes_from_an_earlier_step() -> None:
    # truth: z² on az at 40 sigma and x² on ax at 20 sigma; "first" (z²) enters before "second"
    # (x²). A check takes "second" out (resumed from step 1), then another takes "first" out
    # (resumed from the start, a step before "second" entered): "second" must not come back
    sq_z, sq_x = F[:, 2] ** 2 / G**2, F[:, 0] ** 2 / G**2
    extra = np.zeros((M, 3))
    extra[:, 2] = 40 * SIGMA * sq_z
    extra[:, 0] = 20 * SIGMA * sq_x
    ev = _evidence(8, extra.reshape(-1))
    first, second = _column("first", 2, sq_z), _column("second", 0, sq_x)
    sel = select(ev, [first, second], pose_allowed=False)
    assert [c.effect for c in sel.model.candidates] == ["first", "second"]
    st = WindowState(selection=sel, model=sel.model)
    st, _ = resumed(st, ["second"])
    assert st.model is not None and [c.effect for c in st.model.candidates] == ["first"]
    st, _ = resumed(st, ["first"])
    assert st.excluded == {"first", "second"}
    assert st.model is not None and not st.model.candidates


def test_a_claim_entering_after_a_carried_excess_takes_over_what_it_held() -> None:
    """A true quadratic on z (5e-4/g, 8.5 sigma at ±z) and no excess in the data, with an excess
    of (5 sigma)² on z carried into the selection (``selection.select(excess=...)``): REML
    re-estimates it as the quadratic enters, so the quadratic is admitted and the excess left
    is below sigma², its sampling error on 18 windows (truth 0)."""
    for seed in (2, 4):
        ev = _evidence(seed, _quadratic_z(5e-4))
        st, _ = screen_catalogue(ev, WindowState(), THRESHOLDS)
        model = select(
            ev, list(st.pool), pose_allowed=False, excess=np.array([0.0, 0.0, 25 * SIGMA**2])
        ).model
        assert [c.label for c in model.candidates] == ["nonlinearity_quadratic[z]"], seed
        assert model.noise is not None and model.noise.excess_var is not None
        assert model.noise.excess_var[2] < SIGMA**2, seed
