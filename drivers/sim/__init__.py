"""Simulators of the bench: the rotary table's text-protocol server, the DAQ's Modbus TCP
server, and the truth physics of the sensor on the table (``docs/physics-model.md``).

Used by ``--sim`` runs and the tests; ``bench`` must not import it (import-linter contract).
"""
