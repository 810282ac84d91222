"""The PDF's budget table shows two significant digits, trailing zeros included (GUM 7.2.6):
U = 3.96e-5 rounds to 4.0e-5 and must not print as the one-digit 4e-05."""

from __future__ import annotations

from station.certificates.pdf_budget import _rows


def _budget(u_c: float, U: float) -> dict[str, object]:
    line = {
        "name": "Type A",
        "group": "Type A",
        "channel": None,
        "u": u_c,
        "unit": "",
        "sensitivity": 1.0,
        "contribution": u_c,
    }
    q = {
        "value": 1.5,
        "unit": "V",
        "u_c": u_c,
        "k": 2.0,
        "U": U,
        "nu_eff": "infinite",
        "contributions": [line],
    }
    return {"inputs": [], "quantities": {"b_x": q, "b_y": q, "b_z": q}}


def test_budget_rows_keep_two_significant_digits() -> None:
    rows = {r[0]: r[2:] for r in _rows(_budget(1.97e-5, 3.96e-5), ("b_x", "b_y", "b_z"))}
    assert rows["expanded uncertainty U = k·u_c"] == ("4.0e-05",) * 3
    assert rows["combined standard uncertainty u_c"] == ("2.0e-05",) * 3
    assert rows["Type A"] == ("2.0e-05",) * 3
    rows = {r[0]: r[2:] for r in _rows(_budget(6.0, 12.0), ("b_x", "b_y", "b_z"))}
    assert rows["expanded uncertainty U = k·u_c"] == ("12",) * 3
