"""Two processes configured as different benches (names, data directories) whose bench files
name the same device: the second is refused with one line naming the device and the holder,
whatever the spelling of the device's path; a simulated bench locks nothing. Against a real
pseudo-terminal as the table's serial device."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from api.cli import main
from station.execution.bench_lock import HELD_EXIT, BenchHeld, BenchLock
from station.execution.device_lock import device_key
from station.settings import Settings
from tests.support.pty_bench import write_bench_file


@pytest.fixture
def pty_path() -> Iterator[str]:
    master, slave = os.openpty()
    try:
        yield os.ttyname(slave)
    finally:
        os.close(master)
        os.close(slave)


def settings(tmp_path: Path, name: str, bench_file: Path) -> Settings:
    return Settings(
        data_dir=tmp_path / name,
        database_url=f"sqlite:///{tmp_path / name / 'calbench.db'}",
        bench_name=name,
        bench_file=bench_file,
        device_lock_dir=tmp_path / "device-locks",
    )


def test_a_second_bench_on_the_same_serial_port_is_refused_naming_the_holder(
    tmp_path: Path, pty_path: str
) -> None:
    first_file = write_bench_file(tmp_path / "a.toml", f"serial://{pty_path}", "modbus-tcp://127.0.0.1:1502")
    alias = tmp_path / "ttyTABLE"  # the same port under another name, as /dev/serial/by-id/... is
    alias.symlink_to(pty_path)
    second_file = write_bench_file(
        tmp_path / "b.toml", f"serial://{alias}?baud=9600", "modbus-tcp://127.0.0.1:1503"
    )
    held = BenchLock(settings(tmp_path, "bench-a", first_file), "calbench agent", lease=False).acquire()
    try:
        with pytest.raises(BenchHeld) as refused:
            BenchLock(settings(tmp_path, "bench-b", second_file), "calbench run", lease=False).acquire()
        msg = str(refused.value)
        assert msg.startswith(
            f"bench 'bench-b': the table serial://{alias}?baud=9600 ({pty_path}) is driven by "
        )
        assert f"calbench agent pid {os.getpid()} on host " in msg and "for bench 'bench-a'" in msg
        assert "\n" not in msg
        # the refused process took nothing: its bench is free for another process of its own
        BenchLock(settings(tmp_path, "bench-b", tmp_path / "none.toml"), "x", lease=False).acquire().release()
    finally:
        held.release()
    BenchLock(settings(tmp_path, "bench-b", second_file), "calbench run", lease=False).acquire().release()


def test_the_same_daq_reached_by_two_spellings_is_one_device(tmp_path: Path, pty_path: str) -> None:
    assert device_key("modbus-tcp://LAB-DAQ:502") == device_key("modbus-tcp://lab-daq") == "tcp lab-daq:502"
    assert device_key("socket://10.0.0.5:4001") == "tcp 10.0.0.5:4001"
    master, other = os.openpty()
    try:
        a = write_bench_file(tmp_path / "a.toml", f"serial://{pty_path}", "modbus-tcp://Lab-DAQ")
        b = write_bench_file(tmp_path / "b.toml", f"serial://{os.ttyname(other)}", "modbus-tcp://lab-daq:502")
        with BenchLock(settings(tmp_path, "bench-a", a), "calbench agent", lease=False):
            with pytest.raises(
                BenchHeld, match=r"the DAQ modbus-tcp://lab-daq:502 \(tcp lab-daq:502\) is driven by"
            ):
                BenchLock(settings(tmp_path, "bench-b", b), "calbench agent", lease=False).acquire()
            # a simulated bench drives no device of the file
            BenchLock(
                settings(tmp_path, "bench-c", b), "calbench run", lease=False, sim=True
            ).acquire().release()
    finally:
        os.close(master)
        os.close(other)


def test_calbench_run_on_a_held_device_exits_3_with_one_line(
    tmp_path: Path, pty_path: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bench_file = write_bench_file(tmp_path / "a.toml", f"serial://{pty_path}", "modbus-tcp://127.0.0.1:1502")
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path / "cli"))
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'cli.db'}")
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "bench-cli")
    monkeypatch.setenv("CALBENCH_DEVICE_LOCK_DIR", str(tmp_path / "device-locks"))
    with BenchLock(settings(tmp_path, "bench-agent", bench_file), "calbench agent", lease=False):
        code = main(["run", "static-12", "--unit", "SN-LOCK", "--bench-file", str(bench_file)])
    err = capsys.readouterr().err
    assert code == HELD_EXIT == 3 and err.count("\n") == 1, err
    assert err.startswith(f"calbench run: bench 'bench-cli': the table serial://{pty_path}")
    assert "calbench agent pid" in err and "for bench 'bench-agent'" in err
