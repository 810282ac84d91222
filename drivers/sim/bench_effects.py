"""Bench physics beyond the contract's catalogue, for concealing in simulated runs.

Each is a truth-model effect of ``SensorPhysics`` (docs/physics-model.md, "Bench physics
beyond the catalogue"), with its id and parameters in ``sensor_truth.EFFECT_PARAMETERS``:

- ``table_axis_error`` ``angles_rad`` (k, 2): axis j of the table turns about
  u'_j = Rot(e2_j, b_j)·Rot(e1_j, a_j)·u_j instead of u_j (its parent frame), with
  e1_j = normalise(u_j × c_j), c_j the unit vector of the coordinate least aligned with u_j
  (the first on ties), and e2_j = u_j × e1_j: a gimbal axis not where the drawing says.
- ``angle_harmonic`` ``axis`` (1-based), ``harmonic`` h, ``amplitude_m_s2`` (3,), ``phase_rad``:
  a disturbance locked to that axis's true angle θ, input-referred,
  f += A·sin(h·θ + φ) (a motor's field, a cable's pull, a slip ring's once-per-turn).
- ``periodic_line`` ``frequency_hz``, ``amplitude_m_s2`` (3,), ``phase_rad``: a vibration
  line, f += A·sin(2π·F·t + φ) (mains, a pump, a fan).
- ``clock_drift`` ``delay_s_per_s``: the DAQ clock runs fast against the encoders', so the
  sensor sees the table as it was at t − ρ·t (the delay grows from 0 at the run's start).
- ``hysteresis`` ``axis`` (1-based), ``bias_m_s2`` (3,): the bias remembers the direction
  of the axis's last move, e += b·s(t), s = sign of the axis's last non-zero commanded rate
  (0 before its first move).
- ``encoder_hold`` ``step_deg``: the encoders read in steps of ``step_deg`` and the servo
  holds each pose anywhere within half a step of the commanded reading: the true angles
  of the samples up to the end of window w are θ + u_w, u_w uniform in ±step/2 per axis
  (drawn per window from the run's seed), and the encoders read round(θ / step)·step.
- ``thermal_lag`` ``tau_s``: ``temperature_bias`` follows the temperature of the sensing
  element, a first-order lag of the measured one: τ·Ṫ_e = T − T_e, T_e(0) = T(0).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from drivers.sim.rigid_body import rot

FloatArray = npt.NDArray[np.float64]

BENCH_EFFECT_PARAMETERS: dict[str, dict[str, tuple[int, ...]]] = {
    "table_axis_error": {"angles_rad": (-1, 2)},
    "angle_harmonic": {"axis": (), "harmonic": (), "amplitude_m_s2": (3,), "phase_rad": ()},
    "periodic_line": {"frequency_hz": (), "amplitude_m_s2": (3,), "phase_rad": ()},
    "clock_drift": {"delay_s_per_s": ()},
    "hysteresis": {"axis": (), "bias_m_s2": (3,)},
    "thermal_lag": {"tau_s": ()},
    "encoder_hold": {"step_deg": ()},
}
"""Effect id -> parameter -> shape, beside the contract's catalogue."""


def error_axes(u: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The two directions (3,), (3,) about which an axis u (3,) is turned by ``table_axis_error``."""
    c = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = np.cross(u, c)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def true_axes(axis_vectors: FloatArray, angles_rad: FloatArray) -> FloatArray:
    """(k, 3) the table's true axes under ``table_axis_error`` (module docstring)."""
    out = np.array(axis_vectors, dtype=float, copy=True)
    if angles_rad.shape != (out.shape[0], 2):
        raise ValueError(
            f"effect 'table_axis_error': angles_rad needs ({out.shape[0]}, 2), one pair per table axis"
        )
    for j, u in enumerate(axis_vectors):
        e1, e2 = error_axes(u)
        v = rot(e1, np.array([angles_rad[j, 0]]))[0] @ u
        out[j] = rot(e2, np.array([angles_rad[j, 1]]))[0] @ v
    return out


def axis_index(params: dict[str, FloatArray], k: int, effect: str) -> int:
    """0-based axis of an effect's 1-based ``axis`` parameter, checked against k axes."""
    a = float(params["axis"])
    if a != round(a) or not 1 <= a <= k:
        raise ValueError(f"effect {effect!r}: axis must be an integer from 1 to {k}, got {a:g}")
    return int(a) - 1


def disturbance(fx: dict[str, dict[str, FloatArray]], t_s: FloatArray, angles_rad: FloatArray) -> FloatArray:
    """(n, 3) input-referred disturbances locked to an axis angle or to time (m/s²)."""
    out = np.zeros((t_s.shape[0], 3))
    if "angle_harmonic" in fx:
        p = fx["angle_harmonic"]
        j = axis_index(p, angles_rad.shape[1], "angle_harmonic")
        out += (
            np.sin(float(p["harmonic"]) * angles_rad[:, j] + float(p["phase_rad"]))[:, None]
            * p["amplitude_m_s2"]
        )
    if "periodic_line" in fx:
        p = fx["periodic_line"]
        ph = 2.0 * np.pi * float(p["frequency_hz"]) * t_s + float(p["phase_rad"])
        out += np.sin(ph)[:, None] * p["amplitude_m_s2"]
    return out


def last_direction(rates: FloatArray, previous: float) -> FloatArray:
    """(n,) sign of the last non-zero rate up to each sample, ``previous`` before the first."""
    s = np.sign(rates)
    idx = np.where(s != 0, np.arange(s.size), -1)
    last = np.maximum.accumulate(idx) if s.size else idx
    return np.where(last >= 0, s[np.maximum(last, 0)], previous)


def lagged(
    t_s: FloatArray, temp_c: FloatArray, tau_s: float, state: tuple[float, float] | None
) -> FloatArray:
    """(n,) first-order lag of ``temp_c``, exact for a temperature that takes each sample's value
    over the interval before it.

    :param state: (t, T_e) of the last sample of the previous block, or ``None`` (start settled).
    """
    out = np.empty_like(temp_c)
    t_prev, y = (float(t_s[0]), float(temp_c[0])) if state is None else state
    for i in range(t_s.size):
        y += (1.0 - np.exp(-(t_s[i] - t_prev) / tau_s)) * (temp_c[i] - y)
        t_prev = float(t_s[i])
        out[i] = y
    return out


def hold_offsets_rad(step_deg: float, n_windows: int, k: int, seed: int) -> FloatArray:
    """(n_windows, k) true-angle offsets within half an encoder step (``encoder_hold``, rad)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xE4C0]))
    return np.asarray(np.deg2rad(step_deg) * rng.uniform(-0.5, 0.5, (n_windows, k)), dtype=float)
