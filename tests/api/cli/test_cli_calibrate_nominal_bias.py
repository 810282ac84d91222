"""``calbench calibrate --nominal-scale`` on a V recording needs ``--nominal-bias``: exit 2 with
one line naming the flag, instead of a 'before' |g| check that takes a 1.5 V zero-g output for
0 (mean error ≈ 136 m/s²)."""

from __future__ import annotations

import json

from api.cli import main
from tests.conftest import STATIC_EXAMPLE, copy_example


def test_nominal_scale_without_bias_on_a_v_channel_exits_2(tmp_path, capsys) -> None:
    rec = copy_example(STATIC_EXAMPLE, tmp_path)
    assert main(["calibrate", str(rec), "--json", "--nominal-scale", "0.0176"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "--nominal-bias" in lines[0]
    assert "V channel" in lines[0] and str(rec) in lines[0]

    nominal = ["--nominal-scale", "0.0176", "--nominal-bias", "1.5", "1.5", "1.5"]
    assert main(["calibrate", str(rec), "--json", *nominal]) == 0
    before = json.loads(capsys.readouterr().out)["g_check"]["before"]
    assert abs(before["mean_error_m_s2"]) < 1.0  # the nominal 0.0176 V/(m/s²) is ~2 % off: |err| ≈ 0.2
