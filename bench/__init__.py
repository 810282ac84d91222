"""calbench: accelerometer calibration bench — the bench layer.

Recordings (``bench.recording``), kinematics, procedures as data, the sequencer that runs
them, and the calibration, uncertainty budget and diagnosis of a recording. Layer rule:
from ``drivers`` it imports only ``drivers.base`` and ``drivers.errors`` (the device
protocols), never ``db``, ``station`` or ``api``; ``bench.estimation`` and ``bench.diagnosis`` are pure.
"""

__version__ = "0.1.0"
