"""The station: what runs the calibration bench between the database and the interface.

The bench agent and its supervisor (``agent``), the execution of one procedure on a bench and
its end (``execution``: bench lock, devices, session, verdict, automatic resume after a fault),
the runner and the run queue with their live state and progress hub (``runs``), certificates
and their uncertainty budget (``certificates``), the nightly drift checks (``drift``), the
analysis of uploaded recordings off the event loop (``analysis_worker``), full-disk handling
(``disk_full``) and the settings (``settings``).

Layer rule: below ``api``, above ``db``; it may import ``db``, ``bench`` and ``drivers``
(the simulator only through ``drivers.factory``), never ``api``.
"""
