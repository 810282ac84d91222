"""Table motion of a recording reduced to the regressors of the moving-table model.

From the sampled, unwrapped encoder angles (``docs/recording-format.md``) :func:`prepare_motion`
keeps the angles, their rates and accelerations, the samples the fit may use and the peak
rate (:class:`MotionData`, 81 bytes per sample with three axes); :meth:`MotionData.take`
forms, for the samples a consumer asks for, G = Mᵀ R_inᵀ and B = Mᵀ R_inᵀ A R_in
(``dynamic_model``) and their first and second time derivatives (:class:`MotionSamples`,
432 bytes per sample), so that no (n, 3, 3) product of the whole recording is ever held.

Angle derivatives (the choice for ω̇): the unwrapped encoder angles are differentiated by
a cubic Savitzky–Golay filter over ``DERIVATIVE_WINDOW_S`` (at least 7 samples), so the
encoder quantisation noise in ω̇ stays below 1e-3 rad/s² at 100 Hz–1 kHz (a tangential
error under 1e-4 m/s² at 0.1 m). A cubic is exact for smooth motion but not across a
jump of the angular acceleration (the corners of a trapezoidal rate ramp); samples whose
third-derivative estimate exceeds ``CORNER_JERK_RAD_S3``, and those within half a window
of them, are left out of the fit (``MotionData.valid``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from bench.kinematics import angular_acceleration, angular_velocity, inner_attitude

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

DERIVATIVE_WINDOW_S = 0.07
"""Span of the Savitzky–Golay window for rates, accelerations and Ġ, Ḃ (s)."""
MIN_WINDOW_SAMPLES = 7
GAP_FACTOR = 1.5
"""A time step longer than this many median steps is a gap (dropped DAQ blocks): derivatives
are taken on each stretch between gaps, and a stretch shorter than the window is left out."""
CORNER_JERK_RAD_S3 = 2.0
"""|d³θ/dt³| above this marks a corner of the rate profile (rad/s³); a smooth oscillation
of the procedures stays below 0.3 rad/s³."""
KINEMATICS_CHUNK = 1 << 15
"""Samples whose attitude, rate and acceleration are formed at once in :func:`prepare_motion`
and :meth:`MotionData.take` (with their derivative windows): the rotation products, skew
matrices and G, B before differentiation are (chunk, 3, 3) temporaries, not (n, 3, 3)."""
KEEP_BYTES = 1 << 30
"""The (n, 3, 3) regressors G, Ġ, B, Ḃ, G̈, B̈ are formed once in :func:`prepare_motion` and
kept for the recording's first samples up to this size (432 bytes per sample: 2.5 M samples,
41 min at 1 kHz); the samples beyond are formed per chunk where they are used, each Gauss–Newton
pass again, so a pass costs the kept share's copy plus the rest's forming (about seven times the
CPU time per sample, docs/benchmarks.md) and memory stays at most this size above the chunks'."""
PREDICT_CHUNK = 1 << 15
"""Samples whose prediction or specific force :func:`predict` and :func:`specific_force` form at
once: with ``time_skew`` the corrected regressors G_δ, B_δ and their δ-derivatives are
(chunk, 3, 3) temporaries, not (n, 3, 3)."""


@dataclass(frozen=True)
class MotionSamples:
    """G, B and their time derivatives at chosen samples of a recording (all (m, …)).

    :param t_s: (m,) time (s).
    :param G: (m, 3, 3) Mᵀ R_inᵀ; :param G_dot: its time derivative (1/s).
    :param B: (m, 3, 3) Mᵀ R_inᵀ A R_in (1/s²); :param B_dot: its time derivative (1/s³).
    :param G_ddot: (m, 3, 3) second derivative of G; :param B_ddot: of B.
    :param valid: (m,) samples the fit may use (not at a rate-profile corner).
    """

    t_s: FloatArray
    G: FloatArray
    G_dot: FloatArray
    B: FloatArray
    B_dot: FloatArray
    G_ddot: FloatArray
    B_ddot: FloatArray
    valid: BoolArray

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def take(self, idx: slice | npt.NDArray[np.int64]) -> MotionSamples:
        """The samples ``idx`` (a slice or index array) of these."""
        return MotionSamples(
            self.t_s[idx],
            self.G[idx],
            self.G_dot[idx],
            self.B[idx],
            self.B_dot[idx],
            self.G_ddot[idx],
            self.B_ddot[idx],
            self.valid[idx],
        )


@dataclass(frozen=True)
class MotionData:
    """The table motion of a whole recording, reduced to what the model needs (all (n, …)).

    Holds the angles and their derivatives, and the (n, 3, 3) regressors of the first samples
    that fit in :data:`KEEP_BYTES` (``kept``): :meth:`take` forms them for the other samples, bit
    for bit as a whole-recording computation would (each Savitzky–Golay output depends on the
    ``window`` samples around it, or on the first or last ``window`` samples of its stretch
    near the stretch's ends).

    :param t_s: (n,) time (s).
    :param angles_rad: (n, k) unwrapped axis angles; :param rates_rad_s: (n, k) their rates;
        :param accels_rad_s2: (n, k) their accelerations (zero outside ``runs``).
    :param axis_vectors: (k, 3) unit axes, outermost first; :param mount: (3, 3) mount rotation M.
    :param step_s: median time step h (s); :param window: Savitzky–Golay window (odd, samples).
    :param runs: [a, b) sample ranges between gaps at least ``window`` long.
    :param valid: (n,) samples the fit may use (not at a rate-profile corner).
    :param peak_rate_rad_s: max |ω| (rad/s).
    :param kept: the regressors of samples [0, kept.n), formed once (``None``: all formed where used).
    """

    t_s: FloatArray
    angles_rad: FloatArray
    rates_rad_s: FloatArray
    accels_rad_s2: FloatArray
    axis_vectors: FloatArray
    mount: FloatArray
    step_s: float
    window: int
    runs: tuple[tuple[int, int], ...]
    valid: BoolArray
    peak_rate_rad_s: float
    kept: MotionSamples | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def take(self, idx: slice | npt.NDArray[np.int64]) -> MotionSamples:
        """G, B and their derivatives at the samples ``idx`` (a slice or index array), in its order.

        From ``kept`` for the samples it holds; the others formed :data:`KINEMATICS_CHUNK`
        samples of derivative windows at a time, so a slice of the whole recording holds
        (chunk, 3, 3) temporaries beside its (len(idx), 3, 3) result.
        """
        if self.kept is not None and self.kept.n == self.n:
            return self.kept.take(idx)
        sel = np.arange(*idx.indices(self.n)) if isinstance(idx, slice) else np.asarray(idx, dtype=np.int64)
        if self.kept is not None and np.any(sel < self.kept.n):  # the kept first samples, the rest formed
            old = sel < self.kept.n
            mine, rest = self.kept.take(sel[old]), self._formed(sel[~old])
            parts = [np.empty((sel.size, 3, 3)) for _ in range(6)]
            for name, o in zip(_REGRESSORS, parts, strict=True):
                o[old], o[~old] = getattr(mine, name), getattr(rest, name)
            G, G_dot, B, B_dot, G_ddot, B_ddot = parts
            return MotionSamples(self.t_s[sel], G, G_dot, B, B_dot, G_ddot, B_ddot, self.valid[sel])
        return self._formed(sel)

    def _formed(self, sel: npt.NDArray[np.int64]) -> MotionSamples:
        """G, B and their derivatives formed at the samples ``sel`` (index array), in its order."""
        pts, inv = np.unique(sel, return_inverse=True)
        out = [np.empty((pts.size, 3, 3)) for _ in range(6)]
        for piece in _pieces(self, pts):
            for o, v in zip(out, self._regressors(pts[piece]), strict=True):
                o[piece] = v
        if not np.array_equal(pts, sel):
            out = [o[inv.reshape(-1)] for o in out]
        G, G_dot, B, B_dot, G_ddot, B_ddot = out
        return MotionSamples(self.t_s[sel], G, G_dot, B, B_dot, G_ddot, B_ddot, self.valid[sel])

    def _kinematics(self, pos: npt.NDArray[np.int64]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """G, B (len(pos), 3, 3) and ω (len(pos), 3) at the samples ``pos``, sample by sample."""
        q, rates = self.angles_rad[pos], self.rates_rad_s[pos]
        R_in = inner_attitude(self.axis_vectors, q)
        G = np.einsum("ji,njk->nik", self.mount, np.transpose(R_in, (0, 2, 1)))
        omega = angular_velocity(self.axis_vectors, q, rates)
        W = _skew(omega)
        A = _skew(angular_acceleration(self.axis_vectors, q, rates, self.accels_rad_s2[pos])) + W @ W
        return G, G @ A @ R_in, omega

    def _regressors(self, pts: npt.NDArray[np.int64]) -> tuple[FloatArray, ...]:
        """G, Ġ, B, Ḃ, G̈, B̈ at the sorted distinct samples ``pts`` (one piece of :meth:`take`).

        Each sample inside a run needs G, B on its derivative window [p − h, p + h] (h = window // 2),
        or on the run's first or last ``window`` samples near the run's ends (the filter's
        ``mode="interp"`` edge fit). Overlapping windows are merged into stretches; stretches
        that reach a run's end are differentiated on their own (their edge fit is the run's),
        the others concatenated and differentiated at once (a sample h or more from a stretch's
        ends sees only its own stretch). Outside the runs the derivatives are zero.
        """
        w, h, n = self.window, self.window // 2, pts.size
        out = [np.zeros((n, 3, 3)) for _ in range(6)]
        run_a = np.array([a for a, _ in self.runs], dtype=np.int64)
        run_b = np.array([b for _, b in self.runs], dtype=np.int64)
        r = np.searchsorted(run_a, pts, side="right") - 1
        inside = (r >= 0) & (pts < run_b[np.maximum(r, 0)])
        if not inside.all():  # outside the runs: G, B only
            G, B, _ = self._kinematics(pts[~inside])
            out[0][~inside], out[2][~inside] = G, B
        if not inside.any():
            return tuple(out)
        p, r = pts[inside], r[inside]
        ra, rb = run_a[r], run_b[r]
        lo = np.maximum(ra, np.minimum(p - h, rb - w))
        hi = np.minimum(rb, np.maximum(p + h + 1, ra + w))
        new = np.ones(p.size, dtype=bool)
        new[1:] = (lo[1:] > hi[:-1]) | (r[1:] != r[:-1])
        first = np.flatnonzero(new)
        last = np.append(first[1:], p.size) - 1
        s_lo, s_hi = lo[first], hi[last]
        s_len = s_hi - s_lo
        s_off = np.concatenate([[0], np.cumsum(s_len)[:-1]])
        pos = np.concatenate([np.arange(a, b) for a, b in zip(s_lo, s_hi, strict=True)])
        G, B, _ = self._kinematics(pos)
        d = [np.empty_like(G) for _ in range(4)]  # Ġ, Ḃ, G̈, B̈ at pos
        edge = (s_lo == ra[first]) | (s_hi == rb[last])
        groups = [np.arange(o, o + m) for o, m in zip(s_off[edge], s_len[edge], strict=True)]
        if not edge.all():
            groups.append(
                np.concatenate([np.arange(o, o + m) for o, m in zip(s_off[~edge], s_len[~edge], strict=True)])
            )
        from scipy.signal import savgol_filter  # moving recordings only: a static path stays without it

        for g in groups:
            for k, (x, deriv) in enumerate(((G, 1), (B, 1), (G, 2), (B, 2))):
                d[k][g] = savgol_filter(x[g], w, 3, deriv=deriv, delta=self.step_s, axis=0, mode="interp")
        at = s_off[np.cumsum(new) - 1] + (p - s_lo[np.cumsum(new) - 1])
        for o, v in zip(out, (G, d[0], B, d[1], d[2], d[3]), strict=True):
            o[inside] = v[at]
        return tuple(out)


_REGRESSORS = ("G", "G_dot", "B", "B_dot", "G_ddot", "B_ddot")


def _pieces(m: MotionData, pts: npt.NDArray[np.int64]) -> list[slice]:
    """Consecutive slices of ``pts`` (sorted, distinct) whose derivative windows together span
    about :data:`KINEMATICS_CHUNK` samples (a window adds at most ``m.window`` samples)."""
    if pts.size == 0:
        return []
    grow = np.minimum(np.diff(pts, prepend=pts[0] - m.window), m.window)
    k = np.cumsum(grow) // KINEMATICS_CHUNK
    cuts = np.flatnonzero(np.diff(k)) + 1
    edges = np.concatenate([[0], cuts, [pts.size]])
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def _skew(v: FloatArray) -> FloatArray:
    z = np.zeros(v.shape[0])
    return np.stack(
        [
            np.stack([z, -v[:, 2], v[:, 1]], 1),
            np.stack([v[:, 2], z, -v[:, 0]], 1),
            np.stack([-v[:, 1], v[:, 0], z], 1),
        ],
        1,
    )


def sample_chunks(n: int) -> list[slice]:
    """Consecutive slices of at most :data:`PREDICT_CHUNK` samples covering ``range(n)``."""
    return [slice(a, min(a + PREDICT_CHUNK, n)) for a in range(0, n, PREDICT_CHUNK)]


def window_samples(sample_rate_hz: float, window_s: float = DERIVATIVE_WINDOW_S) -> int:
    """Odd Savitzky–Golay window length spanning ``window_s``, at least 7 samples."""
    w = max(MIN_WINDOW_SAMPLES, round(window_s * sample_rate_hz))
    return w if w % 2 else w + 1


def prepare_motion(
    t_s: npt.ArrayLike,
    angles_rad_unwrapped: npt.ArrayLike,
    axis_vectors: npt.ArrayLike,
    mount: npt.ArrayLike,
    *,
    window_s: float = DERIVATIVE_WINDOW_S,
    keep_bytes: int | None = None,
) -> MotionData:
    """The motion of a recording from its sampled encoder angles (:class:`MotionData`).

    :param t_s: (n,) uniformly sampled time (s; steps within 5 % of the median), gaps allowed.
    :param angles_rad_unwrapped: (n, k) unwrapped axis angles (rad).
    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param mount: (3, 3) mount rotation M.
    :param keep_bytes: keep the regressors up to this size (bytes; ``None``: :data:`KEEP_BYTES`).
    :raises ValueError: too few samples, non-uniform (other than gaps) or non-increasing time.
    """
    t = np.asarray(t_s, dtype=float).reshape(-1)
    q = np.asarray(angles_rad_unwrapped, dtype=float)
    q = q[:, None] if q.ndim == 1 else q
    if t.shape[0] < MIN_WINDOW_SAMPLES or q.shape[0] != t.shape[0]:
        raise ValueError(
            f"motion needs >= {MIN_WINDOW_SAMPLES} samples and one angle row per time, "
            f"got t {t.shape}, angles {q.shape}"
        )
    dt = np.diff(t)
    h = float(np.median(dt))
    gap = dt > GAP_FACTOR * h
    if not (np.all(np.isfinite(t)) and np.all(dt > 0)) or np.max(np.abs(dt[~gap] - h)) > 0.05 * h:
        raise ValueError(
            "motion: time stamps must be finite, increasing and uniform within 5 % of the step "
            f"(gaps longer than {GAP_FACTOR} steps are allowed)"
        )
    w = window_samples(1.0 / h, window_s)
    cuts = np.concatenate([[0], np.flatnonzero(gap) + 1, [t.shape[0]]])
    runs = [(int(a), int(b)) for a, b in itertools.pairwise(cuts) if b - a >= w]
    if not runs:
        raise ValueError(f"motion: no stretch without gaps as long as the {w}-sample derivative window")
    usable = np.zeros(t.shape[0], dtype=bool)
    for a, b in runs:
        usable[a:b] = True

    from scipy.signal import savgol_filter  # moving recordings only: a static path stays without it

    def sg(x: FloatArray, deriv: int) -> FloatArray:
        """Savitzky–Golay derivative of x along time, run by run between gaps (zero outside runs)."""
        if runs == [(0, x.shape[0])]:  # one run without gaps: the filter's own output, no zeroed copy
            return np.asarray(
                savgol_filter(x, w, 3, deriv=deriv, delta=h, axis=0, mode="interp"), dtype=float
            )
        out = np.zeros_like(x)
        for a, b in runs:
            out[a:b] = savgol_filter(x[a:b], w, 3, deriv=deriv, delta=h, axis=0, mode="interp")
        return out

    rates, accels, jerk = sg(q, 1), sg(q, 2), sg(q, 3)
    corner = np.any(np.abs(jerk) > CORNER_JERK_RAD_S3, axis=1)
    del jerk
    if corner.any():
        corner = np.convolve(corner.astype(float), np.ones(w), mode="same") > 0
    corner |= ~usable
    axes = np.asarray(axis_vectors, dtype=float)
    peak_rate = 0.0
    for a in range(0, t.shape[0], KINEMATICS_CHUNK):  # chunks only bound the (chunk, 3, 3) temporaries
        s = slice(a, a + KINEMATICS_CHUNK)
        omega = angular_velocity(axes, q[s], rates[s])
        peak_rate = max(peak_rate, float(np.max(np.linalg.norm(omega, axis=1))))
    motion = MotionData(
        t_s=t,
        angles_rad=q,
        rates_rad_s=rates,
        accels_rad_s2=accels,
        axis_vectors=axes,
        mount=np.asarray(mount, dtype=float).reshape(3, 3),
        step_s=h,
        window=w,
        runs=tuple(runs),
        valid=~corner,
        peak_rate_rad_s=peak_rate,
    )
    limit = KEEP_BYTES if keep_bytes is None else keep_bytes
    n_kept = min(t.shape[0], max(limit, 0) // (6 * 9 * 8))
    if n_kept > 0:
        motion = replace(motion, kept=motion.take(slice(0, n_kept)))
    return motion
