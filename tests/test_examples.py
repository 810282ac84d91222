"""The shipped example recordings: what examples/README.md says made them, small, their truth
recovered, and the README's example commands run from a fresh clone with nothing beside it."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from api.cli import main
from bench.calibration import calibrate_recording
from bench.calibration.diagnose import diagnose_recording
from bench.recording import read_recording
from bench.recording.writer import write_recording
from tests.conftest import EXAMPLES, MOVING_EXAMPLE, REPO_ROOT, STATIC_EXAMPLE

MAX_EXAMPLES_BYTES = 600_000
"""The examples stay small: a few hundred KB in all."""


def _commands(readme: Path, prefix: str) -> list[list[str]]:
    """The indented command lines of a README that start with ``prefix``, split like a shell."""
    return [
        shlex.split(line.strip())
        for line in readme.read_text().splitlines()
        if line.startswith(f"    {prefix}")
    ]


REL_ROUNDING = 1e-12
"""Two numbers a simulation writes agree when within this relative difference: the same
computation's last bits differ between CPUs (numpy's vectorised exp and sin take the
instructions a CPU has), while any change of the simulation or the format moves far more."""


def _same_up_to_rounding(ours: str, shipped: str) -> bool:
    """The same text, field by field (split at commas, colons, brackets, spaces and line ends),
    except that two fields that both read as numbers may differ by ``REL_ROUNDING``."""
    a, b = re.split(r"([,:\[\]{}\s]+)", ours), re.split(r"([,:\[\]{}\s]+)", shipped)
    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        if x == y:
            continue
        try:
            fx, fy = float(x), float(y)
        except ValueError:
            return False
        if not abs(fx - fy) <= REL_ROUNDING * max(abs(fx), abs(fy)):
            return False
    return True


def test_same_up_to_rounding_tells_a_last_bit_from_a_change() -> None:
    assert _same_up_to_rounding("t,ax\n1.5,23.46456846793577\n", "t,ax\n1.5,23.464568467935766\n")
    assert not _same_up_to_rounding("t,ax\n1.5,23.4645684\n", "t,ax\n1.5,23.4645685\n")
    assert not _same_up_to_rounding("t,ax\n1.5,2\n", "t,ay\n1.5,2\n")
    assert not _same_up_to_rounding('{"a": [1, 2]}', '{"a": [1, 2, 3]}')


def test_the_examples_are_what_their_readme_says_and_small(tmp_path: Path) -> None:
    made = _commands(EXAMPLES / "README.md", "calbench simulate ")
    assert len(made) == 2
    for argv in made:
        out = Path(argv[argv.index("-o") + 1])
        assert out.parent == Path("examples"), argv
        argv[argv.index("-o") + 1] = str(tmp_path / out.name)
        assert main(argv[1:]) == 0, argv
        for suffix in (".csv", ".json", ".truth.json"):
            ours, shipped = tmp_path / f"{out.stem}{suffix}", EXAMPLES / f"{out.stem}{suffix}"
            assert _same_up_to_rounding(ours.read_text(), shipped.read_text()), (
                f"{shipped} is not what `{shlex.join(argv)}` makes: run the commands of "
                "examples/README.md again with --overwrite"
            )
    assert sum(p.stat().st_size for p in EXAMPLES.iterdir()) < MAX_EXAMPLES_BYTES


@pytest.mark.parametrize("stem", [STATIC_EXAMPLE, MOVING_EXAMPLE])
def test_an_example_read_and_written_again_is_the_same_bytes(tmp_path: Path, stem: str) -> None:
    rec = read_recording(EXAMPLES / f"{stem}.csv")
    write_recording(rec, tmp_path / f"{stem}.csv")
    for suffix in (".csv", ".json"):
        assert (tmp_path / f"{stem}{suffix}").read_bytes() == (EXAMPLES / f"{stem}{suffix}").read_bytes(), (
            suffix
        )


def test_the_static_examples_concealed_nonlinearity_is_found_at_its_true_size() -> None:
    path = EXAMPLES / f"{STATIC_EXAMPLE}.csv"
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    found = {f.effect: f for f in diagnose_recording(read_recording(path)).findings}
    assert set(found) == {"nonlinearity_quadratic"}
    got, sigma = (
        found["nonlinearity_quadratic"].parameters["k2_per_g"],
        found["nonlinearity_quadratic"].sigma["k2_per_g"],
    )
    z = (np.asarray(got)[2] - truth["effects"]["nonlinearity_quadratic"]["k2_per_g"][2]) / np.asarray(sigma)[
        2
    ]
    assert abs(z) < 3, (got, sigma)


def test_the_moving_examples_lever_arm_is_recovered_within_three_sigma() -> None:
    path = EXAMPLES / f"{MOVING_EXAMPLE}.csv"
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    res = calibrate_recording(read_recording(path)).to_contract()
    assert "lever_arm" in res["terms"]  # the sidecar says no lever arm; the evidence adds it
    r, s = np.asarray(res["extra"]["lever_arm"]["r_m"]), np.asarray(res["extra_sigma"]["lever_arm"]["r_m"])
    z = (r - np.asarray(truth["effects"]["lever_arm"]["r_m"])) / s
    assert np.all(np.abs(z) < 3), z
    K = np.asarray(truth["scale_matrix"])
    zk = (np.asarray(res["scale_matrix"]) - K) / np.asarray(res["scale_matrix_sigma"])
    assert np.all(np.abs(zk) < 4), zk


@pytest.mark.slow
def test_the_readmes_example_commands_run_in_a_fresh_clone_with_nothing_beside_it(tmp_path: Path) -> None:
    if shutil.which("git") is None or not (REPO_ROOT / ".git").exists():
        pytest.skip("not a git checkout (or no git): there is nothing to clone")
    clone = tmp_path / "calbench"
    subprocess.run(["git", "clone", "--quiet", str(REPO_ROOT), str(clone)], check=True, timeout=120)
    assert not (tmp_path / "shared").exists() and (clone / "examples" / f"{STATIC_EXAMPLE}.csv").is_file()
    env = {**os.environ, "PYTHONPATH": str(clone)}
    run_cli = [sys.executable, "-c", "import sys; from api.cli import main; sys.exit(main(sys.argv[1:]))"]
    where = subprocess.run(
        [sys.executable, "-c", "import api; print(api.__file__)"], cwd=clone, env=env,
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert where.stdout.strip().startswith(str(clone)), where.stdout  # the clone's code, not this tree's
    commands = _commands(REPO_ROOT / "README.md", ".venv/bin/calbench ")
    assert {c[1] for c in commands} >= {"calibrate", "diagnose"}, commands
    for argv in commands:
        args = [str(tmp_path / Path(a).name) if a.startswith("/tmp/") else a for a in argv[1:]]
        done = subprocess.run(
            [*run_cli, *args], cwd=clone, env=env, capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 0, (argv, done.stderr)
        assert done.stdout.strip(), argv
        if "--json" in args:
            json.loads(done.stdout)
    assert (tmp_path / "diag.html").read_text().lstrip().lower().startswith("<!doctype html")
