"""``calbench calibrate``: contract JSON, human table, exit 2 with one line on bad input."""

from __future__ import annotations

import json

import pytest

from api.cli import main
from tests.conftest import STATIC_EXAMPLE, copy_example

CONTRACT_KEYS = {
    "unit", "channel_unit", "procedure", "bias", "bias_sigma", "scale_matrix", "scale_matrix_sigma",
    "terms", "extra", "residual_rms", "g_check",
    # added (fields may be added): redundancy and what was not used
    "dof", "zero_redundancy", "unused_windows", "warnings",
    # which bias bias_sigma describes
    "bias_reference",
}  # fmt: skip


@pytest.fixture()
def example(tmp_path):
    return copy_example(STATIC_EXAMPLE, tmp_path)


def test_json_output_has_exactly_the_contract_keys(example, capsys) -> None:
    assert (
        main(
            [
                "calibrate",
                str(example),
                "--json",
                "--nominal-scale",
                "0.0176",
                "--nominal-bias",
                "1.5",
                "1.5",
                "1.5",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert set(out) == CONTRACT_KEYS
    assert out["unit"] == "SN-EX-0001" and out["channel_unit"] == "V" and out["procedure"] == "static-12"
    assert len(out["bias"]) == 3 and len(out["bias_sigma"]) == 3
    assert [len(r) for r in out["scale_matrix"]] == [3, 3, 3] and [
        len(r) for r in out["scale_matrix_sigma"]
    ] == [3, 3, 3]
    assert set(out["g_check"]) == {"before", "after"}
    for part in out["g_check"].values():
        assert set(part) == {"mean_error_m_s2", "std_m_s2"}
    # nominal 0.0176 V per m/s² is 1-3 % off the true scales (0.1 to 0.3 m/s² at 1 g): 'before' is
    # far worse than 'after', which the concealed 4 mg z nonlinearity limits to about 0.01 m/s²
    assert out["g_check"]["before"]["std_m_s2"] > 10 * out["g_check"]["after"]["std_m_s2"]


def test_human_output_is_a_table_with_every_window(example, capsys) -> None:
    assert main(["calibrate", str(example)]) == 0
    text = capsys.readouterr().out
    assert "bias (V)" in text and "scale matrix K" in text
    assert sum(line.startswith("pos") for line in text.splitlines()) == 12
    assert "after" in text and "before" not in text.split("|g| check")[-1]


def test_malformed_file_exits_2_with_one_line(example, capsys) -> None:
    lines = example.read_text().splitlines()
    lines[100] = lines[100].replace(",", ",abc", 1)
    example.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", str(example), "--json"]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and "rec.csv" in err[0]


def test_missing_file_and_degenerate_set_exit_2(tmp_path, example, capsys) -> None:
    assert main(["calibrate", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in capsys.readouterr().err
    # only three segments left: too few windows for 12 parameters
    side = json.loads(example.with_suffix(".json").read_text())
    side["segments"] = side["segments"][:3]
    example.with_suffix(".json").write_text(json.dumps(side))
    assert main(["calibrate", str(example), "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at least 4 static windows" in err[0]


def test_missing_sidecar_exits_2_with_one_line(example, capsys) -> None:
    example.with_suffix(".json").unlink()
    assert main(["calibrate", str(example), "--json"]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert cap.out == "" and len(err) == 1 and "rec.json" in err[0] and "sidecar" in err[0]


def test_imucal_annotated_session_prints_per_window_residuals(real_dir, tmp_path, capsys) -> None:
    """The converted imucal session from the command line: one row per pose with its residuals."""
    src = real_dir / "imucal-ferraris" / "annotated_session.csv"
    out = tmp_path / "ann.csv"
    assert main(["convert", "imucal", str(src), "--sample-rate-hz", "204.8", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(out)]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines() if line[:2] in {
        "x_", "y_", "z_"}}  # fmt: skip
    assert sorted(rows) == ["x_a", "x_p", "y_a", "y_p", "z_a", "z_p"]
    # columns: label, t, n, residual x y z (counts), z-scores x y z, |g| error after
    assert rows["z_p"][2] == "881" and float(rows["z_p"][4]) == pytest.approx(-24.85, abs=0.1)
    assert abs(float(rows["z_p"][-1])) < 1e-3


def test_orientation_free_rows_print_one_z_score() -> None:
    """The scalar fit has one residual per window, (|f̂| − g)/σ: one z column, under a |g| header."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from api.cli.calibrate import format_human
    from bench.calibration import calibrate_recording
    from tests.bench.calibration.test_calibration import _hand_recording
    from tests.support.static_sim import G_LOCAL, random_truth

    rng = np.random.default_rng(4)
    b, K = random_truth(rng)
    f = Rotation.random(16, random_state=9).inv().apply([0.0, 0.0, G_LOCAL])
    res = calibrate_recording(
        _hand_recording(f, b, K, rng), nominal_scale=0.0176, nominal_bias=np.full(3, 1.5)
    )
    text = format_human(res).splitlines()
    header = next(line for line in text if line.startswith("window"))
    assert "|g| z-score" in header and "x,y,z" not in header.split("(")[-1]
    rows = [
        line.split()
        for line in text
        if line.split()[:1] and line.split()[0] in {w.label for w in res.windows}
    ]
    assert len(rows) == len(res.windows) == 16
    # label, t-range, n, 3 residuals, 1 z, |g| after, before
    for row, w in zip(rows, res.windows, strict=True):
        assert len(row) == 9
        assert float(row[6]) == pytest.approx(w.normalized_residual[0], abs=0.051)
