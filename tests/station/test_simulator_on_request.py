"""The simulator is loaded only where a bench asks for it (a ``sim://`` URL, through
:mod:`drivers.factory`): the service, the agent and the commands that drive a bench import
none of ``drivers.sim``, and opening a real bench does not load it.

Checked in a fresh interpreter, so modules that other tests imported do not count. The static
side (no module of station or api imports ``drivers.sim`` but the ``calbench simulate``
command) is an import-linter contract (pyproject.toml).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

ENTRY_POINTS = (
    "api.main",
    "api.cli",
    "api.cli.serve",
    "api.cli.agent",
    "api.cli.run",
    "api.cli.resume",
    "station.agent.bench_agent",
    "station.agent.supervisor",
    "station.runs.runner",
    "station.runs.resume",
    "station.execution.session",
    "station.execution.continuation",
    "station.execution.devices",
    "station.analysis_worker",
    "station.drift",
)

_PROBE = """
import importlib, json, sys
for name in sys.argv[1:]:
    importlib.import_module(name)
loaded_on_import = sorted(m for m in sys.modules if m.startswith("drivers.sim"))
from drivers.errors import DriverError
from drivers.factory import open_bench
try:
    open_bench("loop://", "modbus-tcp://127.0.0.1:1", timeout_s=0.2)
    opened = "opened"
except DriverError as exc:
    opened = type(exc).__name__
loaded_on_open = sorted(m for m in sys.modules if m.startswith("drivers.sim"))
from drivers.factory import simulated_unit
simulated_unit("SN-1", 0.0)
loaded_on_request = "drivers.sim.physics" in sys.modules
print(json.dumps([loaded_on_import, opened, loaded_on_open, loaded_on_request]))
"""


def test_production_code_loads_the_simulator_only_on_request() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, *ENTRY_POINTS],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    loaded_on_import, opened, loaded_on_open, loaded_on_request = json.loads(out.stdout.splitlines()[-1])
    assert loaded_on_import == []
    # loop:// echoes every command: a real table URL that answers wrongly, refused by the driver
    assert opened == "ProtocolError"
    assert loaded_on_open == []
    assert loaded_on_request is True  # the probe sees the simulator when it is asked for
