"""Runs as the station sees them: queued in the database (``queue``), executed by a runner
(``runner``) with their live state (``live``), progress events published in the process
(``hub``), and the resume of an interrupted run (``resume``). The API reads them back and
streams them: :mod:`api.runs`."""
