"""Runs as the service sees them: queued in the database (``queue``), executed by a runner
(``runner``) with their live state (``live``), progress events published in the process
(``hub``), read back from the database by every API process (``events``) and sent as
server-sent events (``stream``) woken by the database's notifications (``wakeup``), and the
resume of an interrupted run (``resume``)."""
