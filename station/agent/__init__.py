"""The bench agent: the one process per table that owns the table, the DAQ, the sequencer and
the recording (``bench_agent``), and the supervisor with which ``calbench serve`` starts and
watches it (``supervisor``). What it executes is :mod:`station.execution`."""
