"""A simulation speed the DAQ's Modbus link cannot carry is refused up front, naming the limit."""

from __future__ import annotations

from pathlib import Path

import pytest

from api.cli import main
from drivers.daq_registers import LINK_MAX_SAMPLES_S
from station.execution.devices import check_sim_link, open_devices
from station.settings import Settings


@pytest.fixture
def env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'calbench.db'}")
    monkeypatch.delenv("CALBENCH_SIM_SAMPLE_RATE_HZ", raising=False)
    return tmp_path


@pytest.mark.parametrize(
    "command", [["serve", "--sim"], ["agent", "--sim"], ["run", "static-12", "--unit", "SN-1", "--sim"]]
)
def test_speed_50_at_1khz_is_refused_in_one_line_naming_the_link(
    env: Path, command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*command, "--sim-speed", "50"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    # 50 × 1000 Hz = 50 000 samples/s against the link's 20 000: at most ×20 at 1 kHz
    assert "50,000 samples/s" in err and "at most 20,000" in err and "speed of at most 20" in err
    assert not (env / "recordings").exists()


def test_the_limit_is_the_product_of_speed_and_rate() -> None:
    assert LINK_MAX_SAMPLES_S == 20_000.0
    check_sim_link(20.0, 1000.0)  # at the link's bound: accepted
    check_sim_link(200.0, 100.0)
    with pytest.raises(ValueError, match="20,001 samples/s"):
        check_sim_link(200.01, 100.0)
    with pytest.raises(ValueError, match=r"at most 2\b"):
        check_sim_link(2.5, 10_000.0)


def test_the_devices_are_not_opened_beyond_the_link(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, sim_sample_rate_hz=1000.0)
    with pytest.raises(ValueError, match="Modbus link"):
        open_devices(settings, True, 50.0, 0)
