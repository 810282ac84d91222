"""continue_run refuses stored procedure parameters that are not a JSON object."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.run_recorder import RunRecorder
from db.repo.recovery import ResumePoint
from station.execution.continuation import continue_run
from station.settings import Settings


def test_stored_parameters_that_are_not_an_object_are_named(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    axes = tuple(
        TableAxis(n, u)
        for n, u in [("outer", (0.0, 0.0, 1.0)), ("middle", (1.0, 0.0, 0.0)), ("inner", (0.0, 0.0, 1.0))]
    )
    sidecar = Sidecar("SN-P", "V", 100.0, 9.81, procedure="static-12", table=TableGeometry(axes))
    # A list of pairs: dict() would have read it as {"dwell_s": 5.0}.
    rec = RunRecorder.create(path, sidecar, True, {"parameters": [["dwell_s", 5.0]]}, chunk_s=1.0)
    t = np.arange(10) / 100.0
    rec.append(t, np.zeros((10, 3)), np.zeros((10, 3)), np.full(10, 25.0), None)
    rec.close()
    point = ResumePoint("run-1", str(path), 0, None, 0, 0, None)
    with pytest.raises(ValueError, match="stored procedure parameters are not a JSON object") as err:
        continue_run(
            Settings(data_dir=tmp_path), None, "run-1", "SN-P", None, "static-12", {}, point, sim=True
        )
    assert str(path) in str(err.value)
