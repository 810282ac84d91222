"""The text of ``calbench diagnose`` and its JSON say the same thing, on several recordings.

Each recording is diagnosed once; the human text (``format_human``) and the contract object
(``to_contract``) must agree: every finding and discovered term in one is in the other, the
UNEXPLAINED line is there exactly when the JSON has ``unexplained``, the per-channel mismatch
is the same numbers, and the text never says "nowhere beyond the noise" or "explains the
recording to its noise" beside a claim. The recordings include the three where the where-line
once said "nowhere beyond the noise" beside a finding (a settling ring on static-12, a delay
and a low-pass on the two-axis oscillation).
"""

from __future__ import annotations

import re
from typing import Any

import pytest

from api.cli.diagnose import format_human
from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from tests.support.diagnose_cases import CASES, static_recording
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, moving_recording


def _check(rec: Recording) -> None:
    d = diagnose_recording(rec)
    text = format_human(d)
    js: dict[str, Any] = d.to_contract()
    found = re.findall(r"^FOUND (\S+):", text, flags=re.M)
    assert found == [f["effect"] for f in js["findings"]]
    discovered = re.findall(r"^DISCOVERED (\S+) on (\S+):", text, flags=re.M)
    assert discovered == [(x["term"], x["channel"]) for x in js["discovered"]]
    assert ("UNEXPLAINED" in text) == ("unexplained" in js)
    claims = bool(js["findings"] or js["discovered"] or "unexplained" in js)
    assert not (claims and "nowhere beyond the noise" in text), text
    assert not (claims and "explains the recording to its noise" in text), text
    assert (not js["findings"] and not js["discovered"]) == ("findings: none" in text)
    line = next(x for x in text.splitlines() if x.startswith("mismatch (chi2/dof per channel):"))
    shown = dict(re.findall(r"(a[xyz]) ([-\d.]+)", line))
    assert shown == {ch: f"{r:.2f}" for ch, r in js["mismatch"]["channels"].items()}
    assert f"where: {js['mismatch']['where']}" in text


def test_text_and_json_agree_static() -> None:
    _check(static_recording({}, 1))
    c = CASES["settling"]
    _check(c.recording(10 * c.limit, 101))


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["", "time_skew", "sensor_lowpass"])
def test_text_and_json_agree_moving(effect: str) -> None:
    if not effect:
        _check(moving_recording({}, 1))
    else:
        c = DYNAMIC_CASES[effect]
        _check(c.recording(5 * c.limit, 101))
