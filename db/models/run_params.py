"""The keys of ``Run.params``: what a run stores as JSON beside its typed columns.

``params`` holds the procedure's parameters as the run was started (the procedure's own
parameters, the dwell choice, the bench and bench file, the simulated unit's seed, the DAQ
rate) and nothing else. The fit is the run's newest ``fit_model`` row, the sample gaps are
``sample_gap`` rows, the diagnosis and the notes on the analysis are ``run`` columns
(:data:`MOVED_TO_RESULTS`). Control requests (abort, pause, continue, resume) and the service's
bookkeeping (the kind of run, the requested dwell, the drift night, the simulated unit's age,
the latest progress, the final event, the start of finishing, the next automatic resume) are
columns of ``run``; every action is a ``run_audit`` row. Code reads and writes ``params``
through these names only.
"""

from __future__ import annotations

# the procedure's parameters and the run's set-up (written when the run starts)
RUN_ID = "run_id"
PROCEDURE = "procedure"
PARAMETERS = "parameters"
"""The procedure's own parameters (``bench.procedures`` ``Procedure.parameters``)."""
SIM = "sim"
"""``{"seed": int}`` on a simulated bench, else ``None``."""
BENCH = "bench"
BENCH_CONFIG = "bench_config"
"""The bench file's identity (``bench.bench_config.BenchConfig.identity``)."""
SAMPLE_RATE_HZ = "sample_rate_hz"
N_AXES = "n_axes"
N_WINDOWS = "n_windows"
EXPECTED_DURATION_S = "expected_duration_s"
DWELL = "dwell"
"""The dwell choice and why (``bench.records.DwellChoice`` as an object)."""

MOVED_TO_COLUMNS = {
    "service_kind": "kind",
    "request": "requested_dwell_s",
    "drift_night": "drift_night",
    "service_sim_age_days": "sim_age_days",
    "abort_requested": "abort_request",
    "control": "control_seq, control_action",
    "resume_requested": "resume_requested",
    "finishing_since": "finishing_since",
    "auto_resume": "auto_resume",
    "live": "live_progress",
    "service_finished": "final_event",
}
"""Keys ``params`` held before migration 0004 and the ``run`` columns they moved to."""

MOVED_TO_RESULTS = {
    "calibration": "fit_model.contract (the run's newest fit_model row)",
    "diagnosis": "diagnosis",
    "diagnosis_error": "diagnosis_error",
    "certificate_error": "certificate_error",
    "conformity_note": "conformity_note",
    "sample_gaps": "sample_gap rows (one per gap, in order: seq)",
}
"""Keys ``params`` held before migration 0005 and where they moved (``run`` columns unless named)."""
