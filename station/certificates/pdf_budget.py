"""The uncertainty budget section of the certificate PDF (GUM 8, ILAC-P14 5.4).

Four tables, for the biases, the diagonal of K (the scale factors) and its six off-diagonal
(cross-axis) terms: one row per source
(the Type A part, then each group of Type B inputs: its inputs' contributions |c_i|·u(x_i)
added in quadrature), one column per axis, then u_c, ν_eff, k and U. The contributions to
every parameter, with each input's u(x_i) and sensitivity c_i, are in the JSON content
(``results.uncertainty_budget``). Text only comes from the content.
"""

from __future__ import annotations

import math
from typing import Any

from station.certificates.pdf_layout import Flow

AXES = ("x", "y", "z")
TABLES = (
    ("Bias b", ("b_x", "b_y", "b_z")),
    ("Scale factors K_ii", ("K_xx", "K_yy", "K_zz")),
    ("Cross-axis terms K_ij, row x and y", ("K_xy", "K_xz", "K_yx")),
    ("Cross-axis terms K_ij, row y and z", ("K_yz", "K_zx", "K_zy")),
)


def _g(x: float) -> str:
    """Two significant digits, a trailing zero kept (U = 3.96e-5 is "4.0e-05", not "4e-05")."""
    return f"{x:#.2g}".rstrip(".") if x != 0 else "0"


def _input_u(inputs: list[dict[str, Any]], group: str) -> str:
    """u(x_i) of a group's inputs (one value when they share it) with its unit."""
    members = [i for i in inputs if i["group"] == group]
    values = sorted({float(i["u"]) for i in members})
    if not members:
        return ""
    unit = str(members[0]["unit"]).replace("m/s2", "m/s²")
    return f"{'/'.join(_g(v) for v in values)} {unit}".strip()


def _rows(budget: dict[str, Any], names: tuple[str, ...]) -> list[tuple[str, ...]]:
    qs = [budget["quantities"][n] for n in names]
    groups: list[str] = []
    for q in qs:
        for c in q["contributions"]:
            if c["group"] not in groups:
                groups.append(c["group"])
    rows: list[tuple[str, ...]] = []
    for group in groups:
        cells = []
        for q in qs:
            ss = sum(float(c["contribution"]) ** 2 for c in q["contributions"] if c["group"] == group)
            cells.append(_g(math.sqrt(ss)))
        u_text = "from the fit" if group == "Type A" else _input_u(budget["inputs"], group)
        rows.append((group, u_text, *cells))
    rows.append(("combined standard uncertainty u_c", "", *(_g(q["u_c"]) for q in qs)))
    rows.append(
        ("effective degrees of freedom ν_eff", "", *(str(q["nu_eff"]).replace("infinite", "∞") for q in qs))
    )
    rows.append(("coverage factor k", "", *(f"{q['k']:.3g}" for q in qs)))
    rows.append(("expanded uncertainty U = k·u_c", "", *(_g(q["U"]) for q in qs)))
    return rows


def budget_section(f: Flow, c: dict[str, Any]) -> None:
    """Section 5: the budget tables, the rule, and what was not evaluated (or why there is none)."""
    f.heading("5  Uncertainty budget (GUM, JCGM 100:2008)")
    budget = c["results"].get("uncertainty_budget")
    if not isinstance(budget, dict):
        f.paragraph(f"No Type B budget: {c['uncertainty_statement']}")
        return
    unit = c["results"]["bias"]["unit"]
    for title, names in TABLES:
        qunit = budget["quantities"][names[0]]["unit"].replace("m/s2", "m/s²")
        f.subheading(f"{title}: contributions |c_i|·u(x_i) ({qunit})")
        rows = [("Source", "u(x_i)", *(f"{n}" for n in names)), *_rows(budget, names)]
        f.table(rows, widths=(0.36, 0.19, 0.15, 0.15, 0.15), header=True, align="right", size=7.5)
    f.paragraph(f"Rule: {budget['rule']}. Type A: {budget['type_a']}.", size=7.5)
    for note in budget.get("not_evaluated", []):
        f.paragraph(f"Not evaluated: {note}.", size=7.5)
    f.paragraph(
        f"All contributions, sensitivities and inputs ({unit} and SI) are in the certificate's "
        "JSON content (results.uncertainty_budget).",
        size=7.5,
    )
