"""``calbench run`` and ``calbench resume`` through the command's entry point, on the simulated bench."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import sqlalchemy as sa

from api.cli import main
from tests.e2e.helpers import SIM_SPEED


@pytest.fixture
def bench_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'calbench.db'}")
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_SIM_SAMPLE_RATE_HZ", "100")
    return tmp_path


@pytest.mark.slow
def test_run_prints_the_fit_and_the_g_table(bench_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(
        ["run", "static-12", "--unit", "SN-CLI", "--sim", "--sim-speed", str(SIM_SPEED), "--dwell-s", "5"]
    )
    out = capsys.readouterr()
    assert code == 0, out.err
    assert ": PASS" in out.out and "bias:" in out.out and "scale matrix K" in out.out
    assert "|g| check" in out.out and "after" in out.out
    assert "step " in out.err and "%" in out.err  # the progress bar


@pytest.mark.slow
def test_run_json_with_the_dwell_from_a_noise_window(
    bench_env: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["run", "static-12", "--unit", "SN-CLI2", "--sim", "--sim-speed", str(SIM_SPEED), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["outcome"] == "PASS"
    assert out["n_windows"] == 13 and out["dwell"]["source"] == "noise_window"
    assert out["calibration"]["terms"] == ["bias", "scale_matrix"]
    engine = sa.create_engine(f"sqlite:///{bench_env / 'calbench.db'}")
    with engine.connect() as conn:
        params = conn.execute(sa.text("SELECT params FROM run WHERE id = :i"), {"i": out["run_id"]}).scalar()
    engine.dispose()
    stored = json.loads(params) if isinstance(params, str) else params
    assert stored["dwell"]["source"] == "noise_window" and stored["dwell"]["reason"] == out["dwell"]["reason"]


def test_unknown_run_cannot_be_resumed(bench_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["resume", "no-such-run", "--sim"])
    err = capsys.readouterr().err
    assert code == 2 and "no-such-run" in err and "not found" in err
    assert err.count("\n") == 1


def test_unknown_procedure_is_bad_input(bench_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", "static-13", "--unit", "SN-X", "--sim"])
    assert exc.value.code == 2 and "static-13" in capsys.readouterr().err
