"""Runs as the API streams them: read back from the database by every API process
(``events``), sent as server-sent events (``stream``) and woken by the database's
notifications (``wakeup``). Queueing and executing them is :mod:`station.runs`."""
