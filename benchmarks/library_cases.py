"""Out-of-catalogue physics concealed in simulated recordings, for the term library of
``calbench diagnose`` (docs/diagnose.md, "Beyond the catalogue").

The simulator (``drivers/sim``) knows only the catalogue, so each effect here is added to
a simulated recording's raw channel afterwards, sample by sample, from the truth the
recording itself carries: the specific force from the encoder angles (sensor frame, in
g = 9.80665 m/s², ``bench.kinematics``), the sensor temperature, time since the first
sample. The raw channel of ``channel`` gains ``coefficient · x(sample)``.

Scenarios (``CASES``), static-12 recordings of the typical ADXL-like triad (V, 100 Hz,
250 µg/√Hz, 40 µg wander, 30 s windows):

- ``cubic``: f_x³ on ax, third-order nonlinearity (sensor);
- ``cross_square``: f_y² on ax, the x channel rectifying the y input (sensor);
- ``scale_temperature``: f_z·temp on az, a scale factor that follows temperature (sensor;
  temperature cycling ±1.5 °C, so that it is not time);
- ``fixture_temperature``: f_x·temp on ay, the fixture's alignment following temperature
  (bench; a mount that turns the unit about z as it warms);
- ``mount_creep``: f_z·t on ax, the mount creeping during the run (bench; lab default
  warm-up, where temp follows time: the finding must say it cannot be told from f_z·temp);
- ``loose_connector``: an offset on ax alone that changes from window to window (a loose
  connector or ground loop re-seating at each move; bench), 1e-4 V rms, random per window
  (fixed pattern per seed): no base quantity expresses it, so the library cannot name it;
  the diagnosis must claim no catalogue effect for it (the pose error, which could absorb
  it, moves gravity on two channels at once) and say in ``unexplained`` where the mismatch is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from bench.diagnosis import Diagnosis
from bench.diagnosis.evidence import G0_M_S2
from bench.kinematics import attitude, static_specific_force
from bench.recording import Recording
from drivers.sim.physics import TemperatureModel
from tests.support.diagnose_cases import CYCLING_TEMPERATURE, static_recording

Quantity = Callable[[Recording], np.ndarray]


def specific_force_g(rec: Recording) -> np.ndarray:
    """(n, 3) specific force per sample from the encoder angles (sensor frame, g)."""
    geo = rec.sidecar.table
    q = rec.table_rad_unwrapped()
    assert geo is not None and q is not None
    R = attitude(geo.axis_vectors, q, geo.mount_matrix)
    return static_specific_force(R, rec.sidecar.g_local_m_s2) / G0_M_S2


def temp_25(rec: Recording) -> np.ndarray:
    """(n,) sensor temperature − 25 °C."""
    assert rec.temp_c is not None
    return rec.temp_c - 25.0


def time_s(rec: Recording) -> np.ndarray:
    """(n,) time since the first sample (s)."""
    return rec.t_s - rec.t_s[0]


def window_offsets(rec: Recording) -> np.ndarray:
    """(n,) a unit-rms random offset per still segment (fixed by the serial), 0 while moving:
    not a function of any base quantity of the library."""
    seed = sum(rec.sidecar.unit_serial.encode())
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xC0]))
    out = np.zeros(rec.n_samples)
    for seg in rec.sidecar.segments:
        sl = (rec.t_s >= seg.start_s) & (rec.t_s <= seg.end_s)
        out[sl] = rng.standard_normal()
    return out


def conceal(rec: Recording, channel: int, x: np.ndarray, coefficient: float) -> Recording:
    """The recording with ``coefficient · x`` added to raw channel ``channel``."""
    raw = np.array(rec.accel_raw, dtype=float, copy=True)
    raw[:, channel] += coefficient * x
    return replace(rec, accel_raw=raw)


@dataclass(frozen=True)
class LibraryCase:
    """One concealed term.

    :param name: scenario; :param channel: 0, 1, 2; :param term: the contract grammar of the
        truth (``""``: not expressible by the library).
    :param quantity: recording -> (n,) the term per sample.
    :param coefficient: size concealed (V per unit of the term).
    :param temperature: temperature course (``None``: the lab default warm-up).
    """

    name: str
    channel: int
    term: str
    quantity: Quantity
    coefficient: float
    temperature: TemperatureModel | None = None

    def recording(self, seed: int, size: float = 1.0) -> Recording:
        """The simulated recording with the term at ``size`` × ``coefficient``."""
        rec = static_recording({}, seed, temperature=self.temperature)
        return conceal(rec, self.channel, self.quantity(rec), size * self.coefficient)


def _f(i: int, power: int = 1) -> Quantity:
    return lambda r: specific_force_g(r)[:, i] ** power


CASES: dict[str, LibraryCase] = {
    c.name: c
    for c in (
        LibraryCase("cubic", 0, "f_x^3", _f(0, 3), 2.0e-4),
        LibraryCase("cross_square", 0, "f_y^2", _f(1, 2), 1.0e-4),
        LibraryCase(
            "scale_temperature",
            2,
            "f_z*temp",
            lambda r: specific_force_g(r)[:, 2] * temp_25(r),
            1.5e-4,
            CYCLING_TEMPERATURE,
        ),
        LibraryCase(
            "fixture_temperature",
            1,
            "f_x*temp",
            lambda r: specific_force_g(r)[:, 0] * temp_25(r),
            1.5e-4,
            CYCLING_TEMPERATURE,
        ),
        LibraryCase("mount_creep", 0, "f_z*t", lambda r: specific_force_g(r)[:, 2] * time_s(r), 1.0e-6),
        LibraryCase("loose_connector", 0, "", window_offsets, 1.0e-4),
    )
}


@dataclass(frozen=True)
class LibraryScore:
    """How one diagnosis did on a concealed term.

    :param named: the truth's term found on its channel; :param z: (estimate − truth)/sigma.
    :param catalogue: catalogue effects claimed; :param terms: every discovered term (``term[ch]``).
    :param unexplained: an ``unexplained`` block was given.
    """

    named: bool
    z: float
    catalogue: tuple[str, ...]
    terms: tuple[str, ...]
    unexplained: bool


def score(case: LibraryCase, d: Diagnosis, size: float = 1.0) -> LibraryScore:
    """Score a diagnosis against the concealed term."""
    ch = ("ax", "ay", "az")[case.channel]
    hit = next((x for x in d.discovered if x.channel == ch and x.term == case.term), None)
    z = float("nan") if hit is None else (hit.coefficient - size * case.coefficient) / hit.sigma
    return LibraryScore(
        named=hit is not None,
        z=z,
        catalogue=tuple(f.effect for f in d.findings),
        terms=tuple(f"{x.term}[{x.channel}]" for x in d.discovered),
        unexplained=d.unexplained is not None,
    )
