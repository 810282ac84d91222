"""One procedure executed on a bench, by the agent or by ``calbench run`` / ``calbench resume``:
the lock of the process that drives the bench (``bench_lock``), its devices from the bench file
(``devices``), the session that opens them and runs or resumes the procedure (``session``), the
end of the run (``verdict``) and the automatic resume after a fault the bench recovers from
(``fault_retry``)."""
