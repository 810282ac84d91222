"""The truth model every simulated run comes from: table, sensor, every catalogue effect, noise.

Signal chain of :meth:`SensorPhysics.sample`, per block of DAQ time stamps t (docs/physics-model.md
gives every equation and sign):

1. table state: the controller's kinematics (encoder coordinates) at t − delay_s
   (``time_skew``), plus ``encoder_offset`` (θ_true = θ_encoder + offset) and the
   ``settling`` ring -> true angles, rates, accelerations;
2. specific force f (sensor frame) from the true state: gravity reaction
   Rot(x, a)·Rot(y, b)·[0, 0, g] (``table_tilt``), per-window attitude error (``pose_error``),
   centripetal and tangential terms at the sensor position (``lever_arm``) and at each
   axis's proof mass (``proof_mass_offsets``);
3. first-order low-pass (``sensor_lowpass``), input-referred noise, clipping at ±saturation;
4. conversion raw = bias + K·f + diag(K)·(catalogue terms) and rounding to the LSB;
5. encoders read the controller's angles at t, wrapped to [−180°, 180°).

The kinematics are re-implemented in ``drivers/sim/rigid_body.py`` on purpose: this model
is an oracle independent of ``bench.kinematics``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from drivers.sim import bench_effects as bench_fx
from drivers.sim.motion import TableKinematics
from drivers.sim.noise import NoiseSpec, NoiseStream
from drivers.sim.rigid_body import chain_state, rot_xy, specific_force_at
from drivers.sim.sensor_truth import G0_M_S2, SensorTruth
from drivers.sim.temperature import TemperatureModel

__all__ = ["G0_M_S2", "NoiseSpec", "SensorPhysics", "SensorSamples", "SensorTruth", "TemperatureModel"]

FloatArray = npt.NDArray[np.float64]

SETTLING_AMPLITUDE_DEG = 0.05
"""Initial amplitude of the ring after a move (deg)."""
SETTLING_FREQUENCY_HZ = 2.0
"""Ringing frequency of the table structure (Hz)."""
SETTLING_FLOOR_DEG = 1e-4
"""Envelope left after ``settling.duration_s`` (deg)."""
REFERENCE_TEMP_C = 25.0
"""Temperature at which ``temperature_bias`` is zero (°C)."""


@dataclass(frozen=True)
class SensorSamples:
    """One block of simulated samples.

    :param raw: (n, 3) accelerometer outputs (channel units).
    :param encoder_deg: (n, k) encoder readings, wrapped to [−180, 180) (deg).
    :param temp_c: (n,) temperature channel (°C).
    :param bias_wander_m_s2: (n, 3) the slow part of the noise (Gauss-Markov bias instability
        plus bias random walk), input-referred (m/s²): what no single run can tell from bias.
    """

    raw: FloatArray
    encoder_deg: FloatArray
    temp_c: FloatArray
    bias_wander_m_s2: FloatArray


class SensorPhysics:
    """A unit on a table: the truth model, stateful across consecutive blocks.

    :param truth: the unit's true parameters and effects.
    :param axis_vectors: (k, 3) table axes, outermost first (unit vectors, parent frames).
    :param mount: (3, 3) true rotation sensor frame -> innermost table frame.
    :param g_local_m_s2: local gravity (m/s²).
    :param seed: seeds every random stream (noise, temperature reading).
    :param temperature: temperature course; default :class:`TemperatureModel` ().
    :param windows_s: (start_s, end_s) of the static windows, needed by ``pose_error``:
        window w's error holds from the end of window w − 1 to the end of window w (the
        first from the start, the last to the end of the run).
    :param sample_rate_hz: sets the white-noise bandwidth; default: from the first block.
    :param encoder_resolution_deg: encoder step (deg); 0 = exact readings.
    """

    def __init__(
        self,
        truth: SensorTruth,
        axis_vectors: FloatArray,
        mount: FloatArray | None = None,
        g_local_m_s2: float = G0_M_S2,
        *,
        seed: int = 0,
        temperature: TemperatureModel | None = None,
        windows_s: Sequence[tuple[float, float]] | None = None,
        sample_rate_hz: float | None = None,
        encoder_resolution_deg: float = 0.0,
    ) -> None:
        axes = np.atleast_2d(np.asarray(axis_vectors, dtype=float))
        if axes.ndim != 2 or axes.shape[1] != 3 or not np.all(np.isfinite(axes)):
            raise ValueError(f"SensorPhysics: axis_vectors must be finite (k, 3), got shape {axes.shape}")
        if not np.allclose(np.linalg.norm(axes, axis=1), 1.0, atol=1e-6):
            raise ValueError(f"SensorPhysics: axis_vectors must be unit vectors, got {axes.tolist()}")
        M = np.eye(3) if mount is None else np.asarray(mount, dtype=float)
        if M.shape != (3, 3) or not np.allclose(M.T @ M, np.eye(3), atol=1e-6) or np.linalg.det(M) < 0:
            raise ValueError(f"SensorPhysics: mount must be a rotation matrix, got {M.tolist()}")
        if not math.isfinite(g_local_m_s2) or not 9.7 < g_local_m_s2 < 9.9:
            raise ValueError(
                f"SensorPhysics: g_local_m_s2 = {g_local_m_s2!r} is not a value of Earth's gravity"
            )
        self.truth = truth
        self.axis_vectors = axes
        self.mount = M
        self.g_local_m_s2 = float(g_local_m_s2)
        self.temperature = TemperatureModel() if temperature is None else temperature
        self.encoder_resolution_deg = float(encoder_resolution_deg)
        self._fx = truth.effect_arrays()
        k = axes.shape[0]
        if "encoder_offset" in self._fx and self._fx["encoder_offset"]["offset_deg"].shape != (k,):
            raise ValueError(f"effect 'encoder_offset': offset_deg needs {k} values, one per table axis")
        self._true_axes = (
            bench_fx.true_axes(axes, self._fx["table_axis_error"]["angles_rad"])
            if "table_axis_error" in self._fx
            else axes
        )
        for eff in ("angle_harmonic", "hysteresis"):
            if eff in self._fx:
                bench_fx.axis_index(self._fx[eff], k, eff)
        self._last_dir = 0.0  # hysteresis: direction of the axis's last move, across blocks
        self._lag_state: tuple[float, float] | None = None  # thermal_lag: (t, T_e) of the last sample
        self._window_ends: FloatArray | None = None
        if windows_s is not None:
            self._window_ends = np.array([end for _, end in windows_s], dtype=float)
        if "pose_error" in self._fx and self._window_ends is not None:
            n_w = self._fx["pose_error"]["angles_rad"].shape[0]
            n_run = self._window_ends.shape[0]
            if n_run != n_w:
                raise ValueError(f"effect 'pose_error': {n_w} angle pairs given, the run has {n_run} windows")
        self._args = (seed, sample_rate_hz)
        root = np.random.SeedSequence(seed)
        noise_seq, temp_seq = root.spawn(2)
        self._noise = NoiseStream(truth.noise, np.random.default_rng(noise_seq), sample_rate_hz)
        self._temp_rng = np.random.default_rng(temp_seq)
        self._lp_state: tuple[float, FloatArray, FloatArray] | None = None  # (t, x, y) of the last sample

    @property
    def windows_s(self) -> tuple[float, ...] | None:
        """End times of the static windows given at construction (s), or ``None``."""
        return None if self._window_ends is None else tuple(float(e) for e in self._window_ends)

    def with_windows(self, windows_s: Sequence[tuple[float, float]]) -> SensorPhysics:
        """A fresh model (same truth, geometry, seed; new state) that knows the run's static windows."""
        seed, rate = self._args
        return SensorPhysics(
            self.truth,
            self.axis_vectors,
            self.mount,
            self.g_local_m_s2,
            seed=seed,
            temperature=self.temperature,
            windows_s=windows_s,
            sample_rate_hz=rate,
            encoder_resolution_deg=self.encoder_resolution_deg,
        )

    @property
    def encoder_step_deg(self) -> float:
        """The step the encoders read in (deg): ``encoder_hold``'s, else ``encoder_resolution_deg``."""
        if "encoder_hold" in self._fx:
            return float(self._fx["encoder_hold"]["step_deg"])
        return self.encoder_resolution_deg

    # -- table ---------------------------------------------------------------------------------
    def true_table_state(self, kin: TableKinematics) -> tuple[FloatArray, FloatArray, FloatArray]:
        """True (angles_rad, rates_rad_s, accels_rad_s2), each (n, k): encoder offset and settling added."""
        angles = kin.angles_rad.copy()
        rates = kin.rates_rad_s.copy()
        accels = kin.accels_rad_s2.copy()
        if "encoder_offset" in self._fx:
            angles += np.deg2rad(self._fx["encoder_offset"]["offset_deg"])
        if "encoder_hold" in self._fx:
            if self._window_ends is None:
                raise ValueError(
                    "effect 'encoder_hold' needs the run's static windows (SensorPhysics windows_s)"
                )
            u = bench_fx.hold_offsets_rad(
                float(self._fx["encoder_hold"]["step_deg"]),
                self._window_ends.size,
                angles.shape[1],
                self._args[0],
            )
            angles += u[np.clip(np.searchsorted(self._window_ends, kin.t_s, side="left"), 0, u.shape[0] - 1)]
        if "settling" in self._fx:
            if kin.since_rest_s is None:
                raise ValueError(
                    "effect 'settling' needs TableKinematics.since_rest_s (time since each stop)"
                )
            d, dd, ddd = settling_ring(kin.since_rest_s, float(self._fx["settling"]["duration_s"]))
            angles += d
            rates += dd
            accels += ddd
        return angles, rates, accels

    def gravity_base(self, t_s: FloatArray) -> FloatArray:
        """(n, 3) reaction to gravity in the nominal table-base frame (m/s²), tilt and pose error applied."""
        g = np.array([0.0, 0.0, self.g_local_m_s2])
        if "table_tilt" in self._fx:
            a, b = self._fx["table_tilt"]["tilt_rad"]
            g = rot_xy(a, b)[0] @ g
        n = np.asarray(t_s).shape[0]
        if "pose_error" not in self._fx:
            return np.broadcast_to(g, (n, 3))
        if self._window_ends is None:
            raise ValueError("effect 'pose_error' needs the run's static windows (SensorPhysics windows_s)")
        pairs = self._fx["pose_error"]["angles_rad"]
        w = np.clip(np.searchsorted(self._window_ends, t_s, side="left"), 0, pairs.shape[0] - 1)
        P = rot_xy(pairs[:, 0], pairs[:, 1])  # (n_w, 3, 3): true attitude = P_w · nominal
        g_sensor: FloatArray = np.einsum("nji,j->ni", P[w], g)  # P_wᵀ · g
        return g_sensor

    def specific_force(self, kin: TableKinematics) -> FloatArray:
        """(n, 3) ideal specific force in the sensor frame (m/s²) from the true table state.

        Axis i is evaluated at its proof mass r_m + rho_m[i] (innermost table frame).
        """
        angles, rates, accels = self.true_table_state(kin)
        r_inner, omega, omega_dot = chain_state(self._true_axes, angles, rates, accels)
        g = self.gravity_base(kin.t_s)
        r = self._fx["lever_arm"]["r_m"] if "lever_arm" in self._fx else np.zeros(3)
        if "proof_mass_offsets" not in self._fx:
            return specific_force_at(r_inner, omega, omega_dot, self.mount, g, r)
        rho = self._fx["proof_mass_offsets"]["rho_m"]
        cols = [
            specific_force_at(r_inner, omega, omega_dot, self.mount, g, r + rho[i])[:, i] for i in range(3)
        ]
        return np.stack(cols, axis=1)

    # -- sensor --------------------------------------------------------------------------------
    def convert(self, f: FloatArray, t_s: FloatArray, temp_c: FloatArray) -> FloatArray:
        """raw (n, 3) = bias + K·f + diag(K)·(the catalogue's sensor terms), before quantisation.

        :param f: (n, 3) specific force the sensing element sees (m/s²).
        :param t_s: (n,) time since the run's start (s), for ``bias_drift``.
        :param temp_c: (n,) true sensor temperature (°C), for ``temperature_bias``.
        """
        K, fx = self.truth.K, self._fx
        extra = np.zeros_like(f)
        if "nonlinearity_quadratic" in fx:
            extra += fx["nonlinearity_quadratic"]["k2_per_g"] * f * f / G0_M_S2
        if "scale_asymmetry" in fx:
            extra += 0.5 * fx["scale_asymmetry"]["delta"] * np.abs(f)
        if "cross_coupling" in fx:
            products = np.stack([f[:, 0] * f[:, 1], f[:, 0] * f[:, 2], f[:, 1] * f[:, 2]], axis=1)
            extra += products @ fx["cross_coupling"]["c_per_g"].T / G0_M_S2
        if "temperature_bias" in fx:
            extra += fx["temperature_bias"]["tc_m_s2_per_c"] * (
                np.asarray(temp_c)[:, None] - REFERENCE_TEMP_C
            )
        if "bias_drift" in fx:
            extra += fx["bias_drift"]["drift_m_s2_per_s"] * np.asarray(t_s)[:, None]
        return self.truth.bias + f @ K.T + extra * np.diag(K)

    def _bench_terms(
        self, t: FloatArray, kin_enc: TableKinematics, kin_sensor: TableKinematics
    ) -> FloatArray:
        """(n, 3) input-referred bench terms (``bench_effects``): disturbances locked to an axis
        angle or to time, and the bias that remembers the direction of the last move (m/s²)."""
        fx = self._fx
        out = np.zeros((t.shape[0], 3))
        if "angle_harmonic" in fx or "periodic_line" in fx:
            out += bench_fx.disturbance(fx, t, self.true_table_state(kin_sensor)[0])
        if "hysteresis" in fx and t.shape[0]:
            j = bench_fx.axis_index(fx["hysteresis"], kin_enc.rates_rad_s.shape[1], "hysteresis")
            s = bench_fx.last_direction(kin_enc.rates_rad_s[:, j], self._last_dir)
            self._last_dir = float(s[-1])
            out += s[:, None] * fx["hysteresis"]["bias_m_s2"]
        return out

    def _lowpass(self, t: FloatArray, x: FloatArray) -> FloatArray:
        """First-order low-pass, exact for input linear between samples, continued across blocks."""
        tau = float(self._fx["sensor_lowpass"]["tau_s"])
        if self._lp_state is None:
            t_prev, x_prev, y_prev = float(t[0]), x[0], x[0]
            t, x = t[1:], x[1:]
            head: FloatArray = x_prev[None, :]
        else:
            (t_prev, x_prev, y_prev), head = self._lp_state, np.empty((0, 3))
        if t.shape[0] == 0:
            self._lp_state = (t_prev, x_prev, y_prev)
            return head
        dt = np.diff(t, prepend=t_prev)
        phi = np.exp(-dt / tau)
        c = tau * (1.0 - phi) / dt
        b0, b1 = 1.0 - c, c - phi
        if np.allclose(dt, dt[-1], rtol=1e-9, atol=0):
            zi = (b1[-1] * x_prev + phi[-1] * y_prev)[None, :]
            y, _ = lfilter([b0[-1], b1[-1]], [1.0, -phi[-1]], x, axis=0, zi=zi)
        else:
            y = np.empty_like(x)
            xp, yp = x_prev, y_prev
            for i in range(x.shape[0]):
                yp = phi[i] * yp + b0[i] * x[i] + b1[i] * xp
                xp = x[i]
                y[i] = yp
        self._lp_state = (float(t[-1]), x[-1].copy(), np.asarray(y[-1], dtype=float).copy())
        return np.vstack([head, y])

    def sample(
        self,
        t_s: FloatArray,
        kinematics: Callable[[FloatArray], TableKinematics],
        temp_c: FloatArray | None = None,
    ) -> SensorSamples:
        """Simulate the next block of DAQ samples at times ``t_s`` (n,), continuing all state.

        :param kinematics: the controller's motion, evaluated at any times (encoder coordinates).
        :param temp_c: (n,) imposed sensor temperature (°C); default: the temperature model.
        """
        t = np.asarray(t_s, dtype=float).reshape(-1)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ValueError("SensorPhysics.sample: time stamps must be finite and strictly increasing")
        if self._lp_state is not None and t.shape[0] and t[0] <= self._lp_state[0]:
            raise ValueError(f"SensorPhysics.sample: block starts at {t[0]} s, not after the last block")
        delay: FloatArray = np.full(
            t.shape, float(self._fx["time_skew"]["delay_s"]) if "time_skew" in self._fx else 0.0
        )
        if "clock_drift" in self._fx:
            delay = delay + float(self._fx["clock_drift"]["delay_s_per_s"]) * t
        kin_enc = kinematics(t)
        kin_sensor = kinematics(t - delay) if np.any(delay) else kin_enc
        f = self.specific_force(kin_sensor) + self._bench_terms(t, kin_enc, kin_sensor)
        if "sensor_lowpass" in self._fx:
            f = self._lowpass(t, f)
        elif t.shape[0]:
            self._lp_state = (float(t[-1]), f[-1], f[-1])
        white, wander = self._noise.next(t)
        f = f + white + wander
        sat = self.truth.noise.saturation_m_s2
        if sat > 0:
            f = np.clip(f, -sat, sat)
        if temp_c is None:
            temp_true = self.temperature.true_c(t)
            temp_read = self.temperature.reading_c(t, self._temp_rng)
        else:
            temp_true = temp_read = np.asarray(temp_c, dtype=float).reshape(-1)
        if "thermal_lag" in self._fx and t.shape[0]:
            temp_true = bench_fx.lagged(
                t, temp_true, float(self._fx["thermal_lag"]["tau_s"]), self._lag_state
            )
            self._lag_state = (float(t[-1]), float(temp_true[-1]))
        raw = self.convert(f, t, temp_true)
        lsb = self.truth.noise.quantization_lsb
        if lsb > 0:
            raw = np.round(raw / lsb) * lsb
        enc = wrap_deg(np.rad2deg(kin_enc.angles_rad))
        step = self.encoder_step_deg
        if step > 0:
            enc = wrap_deg(np.round(enc / step) * step)
        return SensorSamples(raw=raw, encoder_deg=enc, temp_c=temp_read, bias_wander_m_s2=wander)


def wrap_deg(angle_deg: FloatArray) -> FloatArray:
    """Wrap angles to [−180°, 180°) as an encoder readout does."""
    return np.mod(np.asarray(angle_deg, dtype=float) + 180.0, 360.0) - 180.0


def settling_ring(since_rest_s: FloatArray, duration_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Ring of an axis after it stops: δ(s) = A·exp(−s/τ)·sin(2π·f·s) and its two derivatives (rad).

    A = ``SETTLING_AMPLITUDE_DEG``, f = ``SETTLING_FREQUENCY_HZ``, τ = duration_s / ln(A/floor)
    so that the envelope is ``SETTLING_FLOOR_DEG`` at s = duration_s. Zero where s is inf.
    """
    s = np.asarray(since_rest_s, dtype=float)
    amp = math.radians(SETTLING_AMPLITUDE_DEG)
    tau = duration_s / math.log(SETTLING_AMPLITUDE_DEG / SETTLING_FLOOR_DEG)
    w = 2.0 * math.pi * SETTLING_FREQUENCY_HZ
    finite = np.isfinite(s)
    sf = np.where(finite, s, 0.0)
    env = np.where(finite, amp * np.exp(-sf / tau), 0.0)
    sn, cs = np.sin(w * sf), np.cos(w * sf)
    d = env * sn
    dd = env * (w * cs - sn / tau)
    ddd = env * ((1.0 / tau**2 - w * w) * sn - 2.0 * w / tau * cs)
    return d, dd, ddd
