"""Table motion of a recording reduced to the regressors of the moving-table model.

From the sampled, unwrapped encoder angles (``docs/recording-format.md``) :func:`prepare_motion`
keeps the angles, their rates and accelerations, the samples the fit may use and the peak
rate (:class:`MotionData`, 81 bytes per sample with three axes) and the regressors up to
:data:`KEEP_BYTES`; :meth:`MotionData.take` gives, for the samples a consumer asks for,
G = Mᵀ R_inᵀ and B = Mᵀ R_inᵀ A R_in (``dynamic_model``) and, when asked, their first and
second time derivatives (:class:`MotionSamples`, 144 or 432 bytes per sample), kept or formed,
so that no (n, 3, 3) product beyond the budget is ever held.

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
"""The regressors are formed once in :func:`prepare_motion` and kept up to this size: G and B of
the first samples first (:data:`BASIS_BYTES` a sample: 7.4 M samples, 2 h at 1 kHz), then Ġ, Ḃ,
G̈, B̈ of the first samples in what remains (:data:`RATES_BYTES` a sample: all six for 2.5 M
samples, 41 min at 1 kHz; at 60 min G and B of every sample and the derivatives of the first
32 min). A sample beyond is formed where it is used, each pass again: G, B by the kinematic
chain, the derivatives by the Savitzky–Golay filter on the (kept) G, B around it. Every model
needs G and B on every pass, the derivatives only models with ``time_skew`` and the sensor
rates, so the passes of the other models cost a copy per sample up to 2 h; memory stays at
most this size above the chunks' (docs/benchmarks.md)."""
BASIS_BYTES = 2 * 9 * 8
"""Bytes a sample's G and B take."""
RATES_BYTES = 4 * 9 * 8
"""Bytes a sample's Ġ, Ḃ, G̈, B̈ take."""
PREDICT_CHUNK = 1 << 15
"""Samples whose prediction or specific force :func:`predict` and :func:`specific_force` form at
once: with ``time_skew`` the corrected regressors G_δ, B_δ and their δ-derivatives are
(chunk, 3, 3) temporaries, not (n, 3, 3)."""


@dataclass(frozen=True)
class MotionSamples:
    """G, B and (when formed) their time derivatives at chosen samples of a recording (all (m, …)).

    :param t_s: (m,) time (s).
    :param G: (m, 3, 3) Mᵀ R_inᵀ; :param B: (m, 3, 3) Mᵀ R_inᵀ A R_in (1/s²).
    :param valid: (m,) samples the fit may use (not at a rate-profile corner).
    :param rates: (Ġ, Ḃ, G̈, B̈), each (m, 3, 3) (1/s, 1/s³, 1/s², 1/s⁴), or ``None`` when the
        consumer asked for G and B alone (``MotionData.take(..., rates=False)``); reading
        :attr:`G_dot` … then raises instead of returning anything.
    """

    t_s: FloatArray
    G: FloatArray
    B: FloatArray
    valid: BoolArray
    rates: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def _rate(self, k: int) -> FloatArray:
        if self.rates is None:
            raise ValueError(
                f"{_RATES[k]} was not formed for these samples: MotionData.take(idx, rates=True) forms it"
            )
        return self.rates[k]

    @property
    def G_dot(self) -> FloatArray:
        """(m, 3, 3) dG/dt (1/s)."""
        return self._rate(0)

    @property
    def B_dot(self) -> FloatArray:
        """(m, 3, 3) dB/dt (1/s³)."""
        return self._rate(1)

    @property
    def G_ddot(self) -> FloatArray:
        """(m, 3, 3) d²G/dt² (1/s²)."""
        return self._rate(2)

    @property
    def B_ddot(self) -> FloatArray:
        """(m, 3, 3) d²B/dt² (1/s⁴)."""
        return self._rate(3)

    def take(self, idx: slice | npt.NDArray[np.int64], *, rates: bool = True) -> MotionSamples:
        """The samples ``idx`` (a slice or index array) of these (``rates=False``: without derivatives)."""
        rates_ = None if self.rates is None or not rates else _four(tuple(r[idx] for r in self.rates))
        return MotionSamples(self.t_s[idx], self.G[idx], self.B[idx], self.valid[idx], rates_)


_RATES = ("G_dot", "B_dot", "G_ddot", "B_ddot")


def _four(x: tuple[FloatArray, ...]) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    a, b, c, d = x
    return a, b, c, d


@dataclass(frozen=True)
class KeptRegressors:
    """Regressors formed once in :func:`prepare_motion` for a recording's first samples.

    :param G: (n_basis, 3, 3) and :param B: G and B of samples [0, n_basis).
    :param rates: (Ġ, Ḃ, G̈, B̈) of samples [0, n_rates), n_rates <= n_basis (possibly 0).
    """

    G: FloatArray
    B: FloatArray
    rates: tuple[FloatArray, FloatArray, FloatArray, FloatArray]

    @property
    def n_basis(self) -> int:
        """Samples whose G and B are kept."""
        return int(self.G.shape[0])

    @property
    def n_rates(self) -> int:
        """Samples whose Ġ, Ḃ, G̈, B̈ are kept."""
        return int(self.rates[0].shape[0])


@dataclass(frozen=True)
class MotionData:
    """The table motion of a whole recording, reduced to what the model needs (all (n, …)).

    Holds the angles and their derivatives, and the regressors that fit in :data:`KEEP_BYTES`
    (``kept``): G and B of the first samples first (:data:`BASIS_BYTES` a sample, what every
    model needs), then Ġ, Ḃ, G̈, B̈ (:data:`RATES_BYTES` a sample, needed with ``time_skew`` and by
    the sensor rates) of the first samples in what remains. :meth:`take` forms the others, bit
    for bit as a whole-recording computation would (G and B depend on their sample alone; each
    Savitzky–Golay output on the ``window`` samples around it, or on the first or last
    ``window`` samples of its stretch near the stretch's ends).

    :param t_s: (n,) time (s).
    :param angles_rad: (n, k) unwrapped axis angles; :param rates_rad_s: (n, k) their rates;
        :param accels_rad_s2: (n, k) their accelerations (zero outside ``runs``).
    :param axis_vectors: (k, 3) unit axes, outermost first; :param mount: (3, 3) mount rotation M.
    :param step_s: median time step h (s); :param window: Savitzky–Golay window (odd, samples).
    :param runs: [a, b) sample ranges between gaps at least ``window`` long.
    :param valid: (n,) samples the fit may use (not at a rate-profile corner).
    :param peak_rate_rad_s: max |ω| (rad/s).
    :param kept: the regressors formed once (``None``: all formed where used).
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
    kept: KeptRegressors | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def take(self, idx: slice | npt.NDArray[np.int64], *, rates: bool = True) -> MotionSamples:
        """G, B and (``rates``) Ġ, Ḃ, G̈, B̈ at the samples ``idx`` (a slice or index array), in its order.

        From ``kept`` for the samples it holds; the others formed :data:`KINEMATICS_CHUNK`
        samples (of derivative windows) at a time, so a slice of the whole recording holds
        (chunk, 3, 3) temporaries beside its (len(idx), 3, 3) result. ``rates=False`` (a model
        without ``time_skew``) forms no derivative: the result's :attr:`MotionSamples.rates` is ``None``.
        """
        sel = np.arange(*idx.indices(self.n)) if isinstance(idx, slice) else np.asarray(idx, dtype=np.int64)
        k = self.kept
        if k is not None and (sel.size == 0 or int(sel.max()) < (k.n_rates if rates else k.n_basis)):
            kr = _four(tuple(r[idx] for r in k.rates)) if rates else None
            return MotionSamples(self.t_s[idx], k.G[idx], k.B[idx], self.valid[idx], kr)
        G, B = self._basis(sel)
        out = None
        if rates:
            out = _four(tuple(np.empty((sel.size, 3, 3)) for _ in range(4)))
            have = sel < (0 if k is None else k.n_rates)
            if k is not None and have.any():
                for o, v in zip(out, k.rates, strict=True):
                    o[have] = v[sel[have]]
            if not have.all():
                for o, v in zip(out, self._rates(sel[~have]), strict=True):
                    o[~have] = v
        return MotionSamples(self.t_s[sel], G, B, self.valid[sel], out)

    def _basis(self, sel: npt.NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        """G, B (len(sel), 3, 3) at the samples ``sel``: kept, or formed per sample."""
        k = self.kept
        if k is not None and (sel.size == 0 or int(sel.max()) < k.n_basis):
            return k.G[sel], k.B[sel]
        G, B = np.empty((sel.size, 3, 3)), np.empty((sel.size, 3, 3))
        have = sel < (0 if k is None else k.n_basis)
        if k is not None and have.any():
            G[have], B[have] = k.G[sel[have]], k.B[sel[have]]
        todo = np.flatnonzero(~have)
        for a in range(0, todo.size, KINEMATICS_CHUNK):
            at = todo[a : a + KINEMATICS_CHUNK]
            G[at], B[at], _ = self._kinematics(sel[at])
        return G, B

    def _rates(self, sel: npt.NDArray[np.int64]) -> tuple[FloatArray, ...]:
        """Ġ, Ḃ, G̈, B̈ formed at the samples ``sel`` (index array), in its order."""
        pts, inv = np.unique(sel, return_inverse=True)
        out = [np.empty((pts.size, 3, 3)) for _ in range(4)]
        for piece in _pieces(self, pts):
            for o, v in zip(out, self._derivatives(pts[piece]), strict=True):
                o[piece] = v
        if not np.array_equal(pts, sel):
            out = [o[inv.reshape(-1)] for o in out]
        return tuple(out)

    def _kinematics(self, pos: npt.NDArray[np.int64]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """G, B (len(pos), 3, 3) and ω (len(pos), 3) at the samples ``pos``, sample by sample."""
        q, rates = self.angles_rad[pos], self.rates_rad_s[pos]
        R_in = inner_attitude(self.axis_vectors, q)
        G = np.einsum("ji,njk->nik", self.mount, np.transpose(R_in, (0, 2, 1)))
        omega = angular_velocity(self.axis_vectors, q, rates)
        W = _skew(omega)
        A = _skew(angular_acceleration(self.axis_vectors, q, rates, self.accels_rad_s2[pos])) + W @ W
        return G, G @ A @ R_in, omega

    def _derivatives(self, pts: npt.NDArray[np.int64]) -> tuple[FloatArray, ...]:
        """Ġ, Ḃ, G̈, B̈ at the sorted distinct samples ``pts`` (one piece of :meth:`_rates`).

        Each sample inside a run needs G, B on its derivative window [p − h, p + h] (h = window // 2),
        or on the run's first or last ``window`` samples near the run's ends (the filter's
        ``mode="interp"`` edge fit). Overlapping windows are merged into stretches; stretches
        that reach a run's end are differentiated on their own (their edge fit is the run's),
        the others concatenated and differentiated at once (a sample h or more from a stretch's
        ends sees only its own stretch). Outside the runs the derivatives are zero.
        """
        w, h, n = self.window, self.window // 2, pts.size
        out = [np.zeros((n, 3, 3)) for _ in range(4)]
        run_a = np.array([a for a, _ in self.runs], dtype=np.int64)
        run_b = np.array([b for _, b in self.runs], dtype=np.int64)
        r = np.searchsorted(run_a, pts, side="right") - 1
        inside = (r >= 0) & (pts < run_b[np.maximum(r, 0)])
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
        G, B = self._basis(pos)
        d = [np.empty_like(G) for _ in range(4)]  # Ġ, Ḃ, G̈, B̈ at pos
        edge = (s_lo == ra[first]) | (s_hi == rb[last])
        from scipy.ndimage import convolve1d  # moving recordings only: a static path stays without it
        from scipy.signal import savgol_coeffs, savgol_filter

        for o, m in zip(s_off[edge], s_len[edge], strict=True):
            g = slice(int(o), int(o + m))
            for k, (x, deriv) in enumerate(((G, 1), (B, 1), (G, 2), (B, 2))):
                d[k][g] = savgol_filter(x[g], w, 3, deriv=deriv, delta=self.step_s, axis=0, mode="interp")
        if not edge.all():  # the filter's own convolution, without its edge fit (those outputs go unused)
            inner = zip(s_off[~edge], s_len[~edge], strict=True)
            g_in = np.concatenate([np.arange(o, o + m) for o, m in inner])
            for k, (x, deriv) in enumerate(((G, 1), (B, 1), (G, 2), (B, 2))):
                c = savgol_coeffs(w, 3, deriv=deriv, delta=self.step_s)
                d[k][g_in] = convolve1d(x[g_in], c, axis=0, mode="constant")
        at = s_off[np.cumsum(new) - 1] + (p - s_lo[np.cumsum(new) - 1])
        for o, v in zip(out, d, strict=True):
            o[inside] = v[at]
        return tuple(out)


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
    limit = max(KEEP_BYTES if keep_bytes is None else keep_bytes, 0)
    n_basis = min(t.shape[0], limit // BASIS_BYTES)
    if n_basis == 0:
        return motion
    G, B = np.empty((n_basis, 3, 3)), np.empty((n_basis, 3, 3))
    for a in range(0, n_basis, KINEMATICS_CHUNK):
        s = slice(a, min(a + KINEMATICS_CHUNK, n_basis))
        G[s], B[s], _ = motion._kinematics(np.arange(s.start, s.stop))
    none = np.empty((0, 3, 3))
    motion = replace(motion, kept=KeptRegressors(G, B, (none, none, none, none)))
    n_rates = min(n_basis, (limit - n_basis * BASIS_BYTES) // RATES_BYTES)
    if n_rates > 0:
        motion = replace(motion, kept=KeptRegressors(G, B, _four(motion._rates(np.arange(n_rates)))))
    return motion
