"""One rule for a value with an uncertainty: the certificate's Python and the dashboard's
JavaScript (``api/static/uncertainty.js``) give the same strings, and the strings follow GUM
7.2.6 (U to two significant digits, the value to the same decimal place)."""

from __future__ import annotations

import json
import random
import shutil
import subprocess
from decimal import Decimal
from pathlib import Path

import pytest

from station.certificates.rounding import format_with_uncertainty

JS = Path(__file__).resolve().parents[3] / "api" / "static" / "uncertainty.js"
NODE = shutil.which("node")

KNOWN = [
    ((1.49987, 4.3e-6), "1.4998700 ± 0.0000043"),
    ((1234.5, 96.0), "1235 ± 96"),
    ((0.5, 9.96), "1 ± 10"),  # U rounds up to a new decade: still two significant digits
    ((-1e-5, 0.0125), "0.000 ± 0.013"),  # half-up on the decimal digits; no "-0.000"
    ((1.005, 0.01), "1.005 ± 0.010"),  # 1.005 is below 1.005 in binary: decimal rounding keeps it
    ((-1e-9, 3e-10), "-0.00000000100 ± 0.00000000030"),
    ((123456.0, 4321.0), "123500 ± 4300"),
    ((0.017798, 2.05e-6), "0.0177980 ± 0.0000021"),
    ((2.5, 0.0), "2.5 ± 0"),
    ((float("nan"), 1.0), "–"),
]


def _cases() -> list[tuple[float, float]]:
    rng = random.Random(7)
    out = [c for c, _ in KNOWN]
    for _ in range(400):
        u = 10 ** rng.uniform(-12, 6) * rng.choice([1.0, 1.0, 0.95, 0.995])
        v = rng.choice([1.0, -1.0]) * 10 ** rng.uniform(-12, 7)
        out.append((v, u))
    for _ in range(100):  # ties at the rounding place
        e = rng.randint(-8, 4)
        out.append((float(f"{rng.randint(1, 999)}5e{e - 1}"), float(f"{rng.randint(10, 99)}5e{e - 3}")))
    return out


@pytest.mark.parametrize(("case", "expected"), KNOWN)
def test_known_strings(case: tuple[float, float], expected: str) -> None:
    assert format_with_uncertainty(*case) == expected


def test_value_and_u_end_at_the_same_decimal_and_u_has_two_significant_digits() -> None:
    for v, u in _cases()[len(KNOWN) :]:
        text = format_with_uncertainty(v, u)
        value_s, u_s = text.split(" ± ")
        u_r = Decimal(u_s)
        place = u_r.adjusted() - 1  # the place of U's second significant digit
        assert len(u_r.normalize().as_tuple().digits) <= 2, text
        assert len(value_s.partition(".")[2]) == len(u_s.partition(".")[2]) == max(0, -place), text
        assert abs(u_r - Decimal(repr(u))) <= Decimal(1).scaleb(place) / 2, text
        assert abs(Decimal(value_s) - Decimal(repr(v))) <= Decimal(1).scaleb(place) / 2, text


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_the_dashboard_gives_the_certificates_strings() -> None:
    cases = _cases()
    script = (
        f"import {{ fmtU }} from {json.dumps(JS.as_uri())};\n"
        f"const cases = {json.dumps([[v if v == v else None, u] for v, u in cases])};\n"
        "console.log(JSON.stringify(cases.map(([v, u]) => fmtU(v === null ? NaN : v, u))));\n"
    )
    out = subprocess.run(
        [str(NODE), "--input-type=module", "-e", script],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    js = json.loads(out.stdout)
    py = [format_with_uncertainty(v, u) for v, u in cases]
    mismatches = [(c, p, j) for c, p, j in zip(cases, py, js, strict=True) if p != j]
    assert not mismatches, mismatches[:5]
