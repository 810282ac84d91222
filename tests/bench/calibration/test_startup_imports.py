"""A static recording's calibration and diagnosis load only what a static recording needs: the
moving fit and the moving diagnosis (``bench.calibration.dynamic``, ``bench.diagnosis.dynamic``
and what they import) are imported at the moving-recording branch, checked in a fresh
interpreter as the CLI runs. A static calibration does not load ``scipy.signal`` either: the
Savitzky–Golay derivatives in ``estimation.motion_data`` import it where they run. A static
diagnosis does load it, for what it uses: the Welch spectrum of the periodic-line search in the
window samples (``estimation.spectral_lines``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from api.simulated_recording import write_simulated
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

ROOT = Path(__file__).resolve().parents[3]
MOVING_MODULES = (
    "scipy.signal",
    "bench.estimation.motion_data",
    "bench.calibration.dynamic",
    "bench.diagnosis.dynamic",
)
MOVING_FIT = ("bench.calibration.dynamic", "bench.diagnosis.dynamic")
STATIC_CALIBRATION_SKIPS = ("scipy.signal", *MOVING_FIT)

PROBE = """
import contextlib, io, sys
from api.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(sys.argv[1:])
print(code, *[m for m in {modules!r} if m in sys.modules])
"""


@pytest.fixture(scope="module")
def static_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("startup") / "static.csv"
    physics = SensorPhysics(SensorTruth.typical("V", seed=2), DEFAULT_AXES, None, 9.81, seed=3)
    write_simulated(path, simulate_static(static12_poses_deg(), 2.0, physics, 100.0), serial="SN-S", seed=3)
    return path


def _loaded(*argv: str, modules: tuple[str, ...] = MOVING_FIT) -> list[str]:
    """The exit code and which of ``modules`` ``calbench ARGV`` loaded, in a fresh process."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(modules=modules), *argv],
        capture_output=True, text=True, env=env, cwd=ROOT, timeout=300, check=True,
    )  # fmt: skip
    return out.stdout.split()


@pytest.mark.parametrize("command", [("calibrate", "--json"), ("calibrate",)])
def test_a_static_calibration_does_not_load_the_moving_fit(
    static_recording: Path, command: tuple[str, ...]
) -> None:
    argv = (command[0], str(static_recording), *command[1:])
    assert _loaded(*argv, modules=STATIC_CALIBRATION_SKIPS) == ["0"]


def test_a_static_diagnosis_does_not_load_the_moving_fit_or_diagnosis(static_recording: Path) -> None:
    assert _loaded("diagnose", str(static_recording), "--json") == ["0"]


def test_the_probe_sees_the_moving_stack_when_it_is_loaded(static_recording: Path) -> None:
    """The same probe, after asking for the moving fit and diagnosis, names every module: the
    tests above can fail."""
    # scipy.signal is imported where a derivative or a spectrum is computed, not with the modules
    moving = (
        "import bench.calibration as c\nimport bench.diagnosis.dynamic\nc.calibrate_dynamic\n"
        "import scipy.signal"
    )
    probe = PROBE.replace("from api.cli import main", "from api.cli import main\n" + moving)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", probe.format(modules=MOVING_MODULES), "calibrate", str(static_recording)],
        capture_output=True, text=True, env=env, cwd=ROOT, timeout=300, check=True,
    )  # fmt: skip
    assert out.stdout.split() == ["0", *MOVING_MODULES]
