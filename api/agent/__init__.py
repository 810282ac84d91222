"""The bench agent: the one process per table that owns the table, the DAQ, the sequencer and
the recording (``bench_agent``), the session that opens the devices and executes a procedure
(``session``), and the supervisor with which ``calbench serve`` starts and watches it
(``supervisor``)."""
