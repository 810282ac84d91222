"""The CLI cases of issue 13 (found by mutating a valid recording): exit 2 on one line, or a warning.

Each case once gave a traceback, a message on several lines, or a silently wrong exit 0.
"""

from __future__ import annotations

import csv
import json
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

import pytest

from api.cli import main
from benchmarks.fuzz_cli import classify, mutate_csv, mutate_sidecar

COMMANDS = ("calibrate", "diagnose")


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cli-hardening") / "base.csv"
    argv = ["simulate", "-o", str(path), "--dwell-s", "3", "--sample-rate-hz", "50", "--seed", "7"]
    assert main(argv) == 0
    return path


def _copy(base: Path, tmp_path: Path) -> Path:
    out = tmp_path / "m.csv"
    shutil.copy(base, out)
    shutil.copy(base.with_suffix(".json"), out.with_suffix(".json"))
    return out


def _edit_csv(path: Path, change: Callable[[list[str], list[list[str]]], None]) -> None:
    rows = list(csv.reader(path.open()))
    change(rows[0], rows[1:])
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)


def _edit_sidecar_text(path: Path, change: Callable[[str], str]) -> None:
    p = path.with_suffix(".json")
    p.write_text(change(p.read_text()))


def _run(cmd: str, path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main([cmd, "--json", str(path)])
    out, err = capsys.readouterr()
    return code, out, err


def _expect_one_line(path: Path, capsys: pytest.CaptureFixture[str], *parts: str) -> None:
    for cmd in COMMANDS:
        code, _, err = _run(cmd, path, capsys)
        lines = err.splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith(f"calbench {cmd}: "), (cmd, err)
        for p in parts:
            assert p in lines[0], (p, lines[0])


def test_missing_sidecar_is_exit_2_for_both_commands(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _copy(base, tmp_path)
    path.with_suffix(".json").unlink()
    _expect_one_line(path, capsys, "sidecar of m.csv not found")


def test_deep_sidecar(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _copy(base, tmp_path)
    _edit_sidecar_text(path, lambda t: t.rstrip()[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}")
    _expect_one_line(path, capsys, "nested deeper")


def test_huge_sidecar_integer(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _copy(base, tmp_path)
    side = json.loads(path.with_suffix(".json").read_text())
    text = json.dumps(side).replace(json.dumps(side["g_local_m_s2"]), "9" * 400, 1)
    path.with_suffix(".json").write_text(text)
    _expect_one_line(path, capsys, "integer of 400 digits")


def test_huge_csv_field(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _copy(base, tmp_path)

    def change(_h: list[str], rows: list[list[str]]) -> None:
        rows[10][1] = "1" * 200_000

    _edit_csv(path, change)
    _expect_one_line(path, capsys, "line 12")


@pytest.mark.parametrize("field", ["1_0", "١٢", "１"])
def test_numbers_python_reads_but_a_recording_must_not(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], field: str
) -> None:
    path = _copy(base, tmp_path)

    def change(_h: list[str], rows: list[list[str]]) -> None:
        rows[100][2] = field

    _edit_csv(path, change)
    _expect_one_line(path, capsys, "not a number", "data row 101", "column 'ay'")


def test_angle_offset_by_1e10_deg(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _copy(base, tmp_path)

    def change(h: list[str], rows: list[list[str]]) -> None:
        j = h.index("table_2")
        for r in rows:
            r[j] = repr(float(r[j]) + 1e10)

    _edit_csv(path, change)
    _expect_one_line(path, capsys, "beyond ±1e+06 deg", "column 'table_2'")


@pytest.mark.parametrize("rate", ["1e-300", "1e300"])
def test_sample_rate_against_the_time_column(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], rate: str
) -> None:
    path = _copy(base, tmp_path)
    _edit_sidecar_text(path, lambda t: t.replace('"sample_rate_hz": 50.0', f'"sample_rate_hz": {rate}'))
    _expect_one_line(path, capsys, "sample_rate_hz", "disagrees with the time column")


def test_empty_serial(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _copy(base, tmp_path)
    side = json.loads(path.with_suffix(".json").read_text())
    side["unit"]["serial"] = ""
    path.with_suffix(".json").write_text(json.dumps(side))
    _expect_one_line(path, capsys, "unit.serial", "empty")


def test_quarter_turn_encoder_zero_is_flagged(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The inner axis off by 90°: a perfect fit in a turned frame (K moves by thousands of sigma)."""
    path = _copy(base, tmp_path)

    def change(h: list[str], rows: list[list[str]]) -> None:
        j = h.index("table_3")
        for r in rows:
            r[j] = repr(float(r[j]) + 90.0)

    _edit_csv(path, change)
    code, out, err = _run("calibrate", path, capsys)
    assert code == 0 and json.loads(out)["bias"]
    assert "warning" in err and "turned 90.0°" in err
    _, _, base_err = _run("calibrate", base, capsys)
    assert "warning" not in base_err


def test_warnings_before_bad_input_do_not_make_more_lines(
    base: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def warn_then_refuse(*_a: object, **_k: object) -> None:
        warnings.warn("invalid value encountered in divide", RuntimeWarning, stacklevel=1)
        raise ValueError("the recording has no static window")

    monkeypatch.setattr("bench.calibration.analysis.analyse", warn_then_refuse)
    code, _, err = _run("calibrate", base, capsys)
    assert code == 2 and err == "calbench calibrate: the recording has no static window\n"


@pytest.mark.parametrize("seed", range(6))
def test_mutants_never_traceback(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], seed: int
) -> None:
    """A few mutants of the benchmark fuzzer (``make fuzz`` runs 800): no bug class."""
    import random

    rng = random.Random(seed)
    text = base.read_text()
    side = json.loads(base.with_suffix(".json").read_text())
    path = tmp_path / "m.csv"
    new_csv, _ = mutate_csv(text, rng) if seed % 2 else (text, "")
    new_side, _ = (json.dumps(side), "") if seed % 2 else mutate_sidecar(side, rng)
    path.write_bytes(new_csv.encode("utf-8", "surrogateescape"))
    if new_side is not None:
        path.with_suffix(".json").write_text(new_side)
    _, base_out, _ = _run("calibrate", base, capsys)
    for cmd in COMMANDS:
        try:
            code, out, err = _run(cmd, path, capsys)
        except Exception as exc:  # an escaped exception is the bug this test is about
            pytest.fail(f"{cmd}: {type(exc).__name__}: {exc}")
        cls, detail = classify(cmd, code, out, err, json.loads(base_out))
        assert cls in ("ok", "ok, flagged", "exit2"), (cmd, cls, detail)
