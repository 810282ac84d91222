"""Every knob of the diagnosis in one place, each with its default and its reason.

The diagnosis's stages take a :class:`Thresholds` as an argument (``diagnose(ev,
thresholds=...)``, ``diagnose_dynamic(..., thresholds=...)``, ``diagnose_recording(rec,
thresholds=...)``); no module of ``bench.diagnosis`` keeps a threshold of its own
(``tests/bench/diagnosis/test_thresholds.py`` checks it). docs/diagnose.md tabulates them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


@dataclass(frozen=True)
class Thresholds:
    """The diagnosis's knobs; the attribute docstrings are the reasons (docs/diagnose.md)."""

    # --- selection (static, orientation-free and moving) ---------------------------------
    false_alarm: float = 0.01
    """False-alarm probability of one selection step, split evenly (Bonferroni) over the
    candidates tried in that step: a clean recording gets a false finding about once in 100."""
    library_share: float = 0.1
    """Share of ``false_alarm`` the term library may spend in one step (split over its terms):
    the catalogue's gates, and so its detection limits, are unchanged by the library."""
    shortlist: int = 4
    """Candidates re-fitted with their own noise in one step after ranking under the current
    noise (the REML fit is the expensive part; the ranking rarely changes beyond 4)."""
    max_steps: int = 8
    """Most terms one selection adds: more than 8 separate omissions in one recording means the
    model is wrong in a way the catalogue does not describe (``unexplained`` says so)."""
    tie_chi2: float = 6.0
    """Terms whose statistics (or BICs) lie within this are a tie, won by the simplest: a BIC
    difference above 6 is "strong" evidence (Kass & Raftery, JASA 90 (1995) 773)."""
    alike_cosine: float = 0.8
    """Terms whose signatures beyond the model have |cos| above this are alike (ties, mimics)."""
    prescreen: float = 0.25
    """A library term whose statistic under the current noise is below this fraction of its gate
    is not re-fitted under its own noise: re-fitting moves the statistic by far less than 4×."""
    relative_leverage_min: float = 1e-3
    """A column whose part outside the current design is below this fraction of its norm cannot
    be told from the model's other terms on this pose set (reported, not guessed)."""
    confound_cosine: float = 0.8
    """Two effects whose signatures beyond the first-order model have |cos| above this are
    reported as indistinguishable on the recording."""

    # --- catch-all, slow noise and the final tests ---------------------------------------
    physics_alpha: float = 1e-3
    """Lower-tail level at which a channel is said not to show the scatter a pose error implies
    (the catch-all must move every channel it moves in physics)."""
    cap_alpha: float = 1e-3
    """Lower-tail probability of the χ² quantile bounding the slow noise by the windows'
    half-window differences (one-sided 99.9 %)."""
    unexplained_alpha: float = 1e-3
    """Level of the final model's χ² tests (whole, per channel two-sided, channels against each
    other): stricter than a selection step because it is a verdict on the whole model."""
    correlation_significance: float = 0.01
    """Level of the first-order residuals' correlation with the named regressors (Bonferroni
    over channels and regressors, two-sided)."""
    within_window_passes: int = 2
    """Corrections of the window noise for a term that changes within a window, each followed
    by a refit; the second pass moves the coefficients by far less than their sigmas."""
    free_orientation_rad: float = 0.1
    """Orientation-free recordings: standard deviation of each window's orientation about the two
    axes perpendicular to gravity, so that only the magnitude of a reading is evidence."""

    # --- term library --------------------------------------------------------------------
    max_degree: int = 3
    """Highest degree of the library's monomials: one order beyond the catalogue's second-order
    terms; each degree multiplies the terms tried, and so tightens the library's gate."""
    alias_tol: float = 1e-6
    """Two monomials whose signatures beyond the first-order model have |cos| > 1 − this are one
    term (f_x·f_y² and f_x on the ±g poses); two effects whose columns coincide so, and fit
    within ``tie_chi2``, are a tie the catalogue's order decides."""
    min_temperature_span_c: float = 0.05
    """Temperature must vary by more than this over the windows (°C) to say anything about a
    temperature coefficient (below it the channel's own resolution makes the span)."""
    lag_tau_min_s: float = 1.0
    """Shortest thermal-lag time constant searched (s); the longest is the run's span. Below a
    second the lag moves each window mean by the temperature's change over that second: on the
    catalogue's cycling-temperature run the lag's columns from 0.01 s to 1 s trace a curve of
    length 0.02 rad beyond the model (Davies' L), one column, the plain coefficient (τ → 0)."""
    profile_passes: int = 2
    """Passes of a profiled parameter (a thermal lag's τ) profiled again under the final model's
    noise and the noise re-estimated with it before the model is reported: the selection
    profiled it under the noise of its step, whose slow wander still held part of the misfit."""
    lag_grid_ratio: float = 1.25
    """Ratio of neighbouring time constants on the thermal lag's search grid: neighbouring
    columns then agree to |cos| > 0.99 beyond the model (0.994 on the catalogue's
    cycling-temperature run), so the grid's best is within about 1 % in χ² of the continuous
    maximum (``profiled.resolve`` refines it by a parabola in ln τ)."""

    # --- within-window settling ----------------------------------------------------------
    settling_share: float = 0.1
    """Share of ``false_alarm`` the within-window settling test runs at (one test per recording
    over many segments: a tenth keeps it from dominating the clean false-finding rate)."""
    settling_segment_s: float = 2.0
    """Length of one spectral segment (s); frequency resolution 1/segment, 0.5 Hz."""
    settling_early_segments: int = 3
    """Segments at the start of each window that the settling test compares with the rest."""
    settling_broadband_alpha: float = 1e-9
    """Probability under no ring of an early segment-channel's median ratio at which it is taken
    for broadband (an outlying sample: a spike, a flipped byte) and left out of the settling test."""
    settling_ring_decades: float = math.log(0.05 / 1e-4)
    """ln(initial ring amplitude / floor) of the bench's settling convention
    (docs/physics-model.md): the reported duration is the time to ring down by this."""
    encoder_step_deg: float = 1e-3
    """Central-difference step (deg) of an encoder offset's response: small against any offset
    worth reporting, large against rounding of the specific force."""
    table_axis_step_rad: float = 1e-5
    """Central-difference step (rad) of a table axis's direction angles: the response is linear
    to 1e-10 there."""

    # --- moving recordings ---------------------------------------------------------------
    dynamic_ratio_limit: float = 1.3
    """A moving recording's final model fails its noise when a channel's Σ (r/σ_w)² / dof
    exceeds this. Not a χ² quantile: σ_w comes from the samples' second differences and the
    residual carries the bias wander and the motion's own high-frequency content, so clean
    recordings scatter between 0.93 and 1.10 (docs/diagnose.md)."""
    block_s: float = 1.0
    """Block length (s) of a moving recording's block-mean residuals (``where``)."""
    coherence_trend_degree: int = 3
    """Legendre degree of the slow trend taken out of a moving residual's block means before
    their coherence is tested (``dynamic_coherence``): the slow part of a bias wander over one
    run; a step or a disturbance faster than a cubic over the run stays in the test."""
    where_z: float = 4.0
    """A block residual beyond this many sigmas is named in ``where`` (moving recordings)."""
    where_ratio: float = 2.0
    """A channel whose first-order χ²/dof exceeds this is named in ``where`` (static recordings:
    twice the noise is far outside the ratio's scatter for 12 windows or more)."""
    motion_chunk_samples: int = 4000
    """Samples per chunk of the moving library's per-sample scores (memory only: the result does
    not depend on it)."""
    motion_subsample: int = 2000
    """Most samples the moving library's projections use (every stride-th): J and x are smooth
    on this scale, so the projections change by far less than the gates' resolution."""
    motion_refit_iter: int = 5
    """Gauss-Newton iterations of a moving refit with a library term."""
    slow_share: float = 0.5
    """A moving library term more than this share of whose signature beyond the model (in
    energy, cos²) is a slow trend (cubics in t and temp on its channel) is one a bias wander can
    make: not searched."""

    # --- bench physics after the model (``bench_families``) -------------------------------
    bench_false_alarm: float = 1e-3
    """Family-wise false-alarm probability of each bench family's test on one recording (angle
    harmonics, clock drift; the line finder's own is ``spectral_lines.FALSE_ALARM``, also 1e-3):
    a verdict beside a model already chosen, as strict as ``unexplained_alpha``."""
    ar_order: int = 8
    """Order of the autoregression that prewhitens a moving residual: at 100 Hz, 80 ms of memory
    beside the first-order nuisance; the wander's slow part is near a unit root it follows."""
    harmonics: int = 4
    """Harmonics of each table axis's angle searched (a motor's poles, a cable's twist, a slip
    ring's once-per-turn are the first few)."""
    max_harmonic_terms: int = 4
    """Most angle harmonics one moving recording is said to carry; beyond that the disturbance
    is not a few harmonics and ``unexplained`` is the honest answer."""
    min_turn_rad: float = math.pi / 2
    """An axis that turns through less than this is not searched for harmonics of its angle:
    they are then slow functions of a nearly constant angle, a trend rather than a harmonic."""
    line_grid_max: int = 400
    """Most frequencies of a line's refinement on the samples' own clock (memory and time grow
    with it; the parabola through the peak interpolates beyond the grid)."""
    line_block_s: float = 10.0
    """Block length (s) of a moving residual whose mean and slope are fitted beside a line: the
    wander's trend is removed, a line of 0.5 Hz and above keeps ≥ 5 periods per block."""
    move_rate_deg_s: float = 0.5
    """An encoder angle changing faster than this (°/s) is a move (hysteresis's last-move sign);
    an encoder flickering by one count at rest (1e-4° in 10 ms: 0.01°/s) is not."""


THRESHOLDS = Thresholds()
"""The defaults."""


def table() -> list[tuple[str, object, str]]:
    """(name, default, reason) of every knob, in order (docs/diagnose.md's table)."""
    import inspect

    src = inspect.getsource(Thresholds)
    out = []
    for f in fields(Thresholds):
        head = f"    {f.name}:"
        start = src.index(head)
        doc_start = src.index('"""', start) + 3
        doc = " ".join(src[doc_start : src.index('"""', doc_start)].split())
        out.append((f.name, getattr(THRESHOLDS, f.name), doc))
    return out
