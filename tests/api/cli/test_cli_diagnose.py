"""``calbench diagnose``: the JSON contract, the HTML report, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from bench.recording import write_recording
from tests.support.diagnose_cases import static_recording


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "api", "diagnose", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300)


def test_json_contract_and_report(tmp_path: Path) -> None:
    rec = static_recording({"nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 2e-3]}}, seed=5)
    path = tmp_path / "run.csv"
    write_recording(rec, path)
    out = _cli(str(path), "--json", "--report", str(tmp_path / "r.html"))
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert set(doc) >= {"unit", "baseline", "mismatch", "findings", "final"}
    assert set(doc["baseline"]) == {"terms", "residual_rms", "chi2_dof", "bic"}
    assert set(doc["mismatch"]) == {"channels", "where", "correlates_with"}
    assert doc["findings"][0]["effect"] == "nonlinearity_quadratic"
    keys = {"effect", "summary", "parameters", "sigma", "delta_bic", "residual_rms_after"}
    assert set(doc["findings"][0]) == keys
    assert doc["final"]["terms"] == ["bias", "scale_matrix", "nonlinearity_quadratic"]
    assert doc["mismatch"]["channels"]["az"] > 5 * doc["mismatch"]["channels"]["ax"]
    html = (tmp_path / "r.html").read_text()
    assert html.startswith("<!doctype html>") and "<svg" in html and "nonlinearity_quadratic" in html


def test_missing_file_is_bad_input(tmp_path: Path) -> None:
    out = _cli(str(tmp_path / "nope.csv"))
    assert out.returncode == 2 and "nope.csv" in out.stderr and len(out.stderr.strip().splitlines()) == 1
