"""Out-of-catalogue physics on moving recordings: the moving library's table (docs/diagnose.md).

``python -m benchmarks.study_diagnose_library_motion [N] [M]``: for each scenario below, N
simulated 90 s oscillations at 100 Hz (typical triad, V; seeds 100…) with the term concealed
by adding it to one raw channel sample by sample, computed from the recording's own encoder
angles (ω in sensor axes = Rᵀ Σ θ̇_i a_i, Savitzky–Golay rates; gravity's direction Rᵀ e_z),
the simulator knowing only the catalogue; the one-channel delay is the simulator's own delay
taken for one channel. Prints a markdown row per scenario: named on its channel (or an alike
term naming the truth in ``confounded_with``), |z| = |coefficient − truth| / sigma where named
(median / max; the delay in seconds, coefficient / (K_xx g0)), recordings with a catalogue
finding, recordings with ``unexplained``. Then M clean oscillations and M clean rate runs
(seeds 1000…): recordings with any catalogue finding or discovered term.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import savgol_filter

from bench.calibration.diagnose import diagnose_recording
from bench.kinematics import angular_velocity, attitude
from bench.recording import Recording
from tests.support.diagnose_dynamic_cases import moving_recording

G0 = 9.80665
Values = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def motion(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) ω in sensor axes (rad/s) and (n, 3) gravity's direction in sensor axes (g)."""
    geo = rec.sidecar.table
    q = rec.table_rad_unwrapped()
    assert geo is not None and q is not None
    h = float(np.median(np.diff(rec.t_s)))
    wb = angular_velocity(geo.axis_vectors, q, savgol_filter(q, 9, 3, deriv=1, delta=h, axis=0))
    R = attitude(geo.axis_vectors, q, geo.mount_matrix)
    return np.einsum("nji,nj->ni", R, wb), R[:, 2, :]


@dataclass(frozen=True)
class MotionCase:
    """A concealed term: ``term`` on ``channel`` of size ``coefficient`` (``None``: not expressible)."""

    name: str
    term: str | None
    channel: int
    coefficient: float
    values: Values | None = None

    def recording(self, seed: int) -> Recording:
        rec = moving_recording({}, seed)
        raw = rec.accel_raw.copy()
        if self.name == "one_channel_delay":
            raw[:, self.channel] = moving_recording({"time_skew": {"delay_s": 0.005}}, seed).accel_raw[:, 0]
        else:
            assert self.values is not None
            w, f = motion(rec)
            raw[:, self.channel] += self.coefficient * self.values(w, f, rec.t_s - rec.t_s[0])
        return replace(rec, accel_raw=raw)


CASES = (
    MotionCase("one_channel_delay", "fdot_x", 0, -0.005),
    MotionCase("rate_squared_bias", "w_z^2", 2, 3e-4, lambda w, f, t: w[:, 2] ** 2),
    MotionCase("force_times_rate", "f_x*w_y", 0, 3e-4, lambda w, f, t: f[:, 0] * w[:, 1]),
    MotionCase("rate_bias (slip ring)", "w_z", 0, 2e-4, lambda w, f, t: w[:, 2]),
    MotionCase(
        "bias_step (connector, half-way)", None, 0, 1e-3, lambda w, f, t: (t > 0.5 * t[-1]).astype(float)
    ),
)


def row(case: MotionCase, n: int) -> str:
    """One table row."""
    named = alike = cat = unexp = 0
    zs: list[float] = []
    ch = ("ax", "ay", "az")[case.channel]
    for seed in range(100, 100 + n):
        d = diagnose_recording(case.recording(seed))
        cat += bool(d.findings)
        unexp += d.unexplained is not None
        hit = next((x for x in d.discovered if x.channel == ch and x.term == case.term), None)
        if hit is not None:
            named += 1
            scale = d.K[case.channel, case.channel] * G0 if case.name == "one_channel_delay" else 1.0
            zs.append(abs(hit.coefficient / scale - case.coefficient) / (hit.sigma / scale))
        elif case.term and any(x.channel == ch and case.term in x.confounded_with for x in d.discovered):
            alike += 1
        found = [f.effect for f in d.findings] + [f"{x.term}[{x.channel}]" for x in d.discovered]
        print(f"  {case.name} seed {seed}: {found or 'nothing'}; unexplained {d.unexplained is not None}")
    z = f"{np.median(zs):.1f} / {np.max(zs):.1f}" if zs else "–"
    unit = "s (delay)" if case.name == "one_channel_delay" else "V per unit"
    return (
        f"| {case.name} | {case.term or '(not expressible)'} on {ch} | {case.coefficient:.2g} {unit} | "
        f"{named}/{n} | {alike}/{n} | {z} | {cat}/{n} | {unexp}/{n} |"
    )


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args else 6
    m = int(args[1]) if len(args) > 1 else 20
    rows = [row(c, n) for c in CASES]
    print(
        "| scenario | truth | size | named | alike named | abs z (median / max) | catalogue claimed "
        "| unexplained |"
    )
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    for kind in ("oscillation", "rate"):
        claims = {}
        for seed in range(1000, 1000 + m):
            d = diagnose_recording(moving_recording({}, seed, kind=kind))
            found = [f.effect for f in d.findings] + [f"{x.term}[{x.channel}]" for x in d.discovered]
            if found or d.unexplained is not None:
                claims[seed] = (found, d.unexplained is not None)
        print(f"clean {kind}: {len(claims)} of {m} with a claim or unexplained: {claims}")


if __name__ == "__main__":
    main()
