"""The certificate as a PDF, rendered from its JSON content with matplotlib's PDF backend.

A4 pages of monospaced text: the header (title, number, laboratory) and "page n of N" on
every page, "End of certificate" on the last (ISO/IEC 17025 7.8.2.1 d). The content hash
is printed so a reader can check the PDF against the JSON.
"""

from __future__ import annotations

import io
import json
import textwrap
from typing import Any

from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

A4_IN = (8.27, 11.69)
LINES_PER_PAGE = 58
WIDTH_CHARS = 92


def _fmt_matrix(rows: list[list[float]], us: list[list[float]]) -> list[str]:
    return [
        "    " + "   ".join(f"{v: .6e} ± {u:.1e}" for v, u in zip(r, ur, strict=True))
        for r, ur in zip(rows, us, strict=True)
    ]


def _quantity(name: str, q: dict[str, Any]) -> list[str]:
    head = f"  {name} ({q['unit']}), expanded uncertainty U (k = {q['k']:g}):"
    v, u = q["value"], q["expanded_uncertainty"]
    if v and isinstance(v[0], list):
        return [head, *_fmt_matrix(v, u)]
    return [head, "    " + "   ".join(f"{a:.7g} ± {b:.1e}" for a, b in zip(v, u, strict=True))]


def _wrap(text: str, indent: str = "  ") -> list[str]:
    return textwrap.wrap(text, WIDTH_CHARS, initial_indent=indent, subsequent_indent=indent) or [indent]


def certificate_lines(c: dict[str, Any], sha256: str) -> list[str]:
    """The certificate's body as text lines (without page headers)."""
    res, cond, dates = c["results"], c["conditions"], c["dates"]
    lines = [
        f"Laboratory: {c['laboratory']['name']}",
        f"Address: {c['laboratory']['address']}",
        f"Location of calibration: {c['location']}   Bench: {c.get('bench')}",
        f"Customer: {c['customer']['name'] or c['customer']['note']}",
        "",
        "ITEM",
        f"  {c['item']['description']}, serial {c['item']['serial']}, model {c['item']['model'] or 'n/a'}",
        f"  output unit {c['item']['channel_unit']}; condition: {c['item']['condition']}",
        "DATES",
        f"  calibrated {dates['calibration_start']} .. {dates['calibration_end']}",
        f"  issued {dates['issued']}   received: {dates['received'] or 'not recorded'}",
        "METHOD",
        *_wrap(f"{c['method']['procedure']}: {c['method']['description']}"),
        *_wrap("deviations: " + "; ".join(c["method"]["deviations"])),
        "CONDITIONS",
    ]
    t = cond["sensor_temperature"]
    lines.append(
        "  sensor temperature: "
        + (f"{t['mean_c']:.2f} °C (min {t['min_c']:.2f}, max {t['max_c']:.2f})" if t else "not measured")
    )
    g_local = cond["g_local_m_s2"]
    g_text = f"{g_local:.6f} m/s²" if g_local is not None else "not recorded"
    lines.append(f"  local gravity g_local = {g_text}")
    if cond.get("table"):
        lines.extend(_wrap("table: " + json.dumps(cond["table"])))
    lines += ["RESULTS", *_wrap(res["model"]), *_quantity("bias", res["bias"])]
    lines += _quantity("scale_matrix K", res["scale_matrix"])
    rms = res["residual_rms"]["value"]
    lines.append(f"  residual RMS: {'n/a' if rms is None else f'{rms:.2g}'} {res['residual_rms']['unit']}")
    lines.append("|g| CHECK (mean error / std over static windows, m/s²)")
    for when in ("before", "after"):
        g = c["g_check"][when]
        lines.append(
            f"  {when:7s}: " + (f"{g['mean_error_m_s2']} / {g['std_m_s2']}" if g else "not available")
        )
    lines += ["UNCERTAINTY", *_wrap(c["uncertainty_statement"])]
    diag = c["diagnosis"]
    lines += ["DIAGNOSIS", *_wrap(diag["note"])]
    for f in diag["findings"]:
        lines += _wrap(f"- {f['effect']}: {f['summary']}", "    ")
    lines += ["CONFORMITY", *_wrap(c["conformity"]), "TRACEABILITY", *_wrap(c["traceability"])]
    lines += ["STATEMENTS", *[x for s in c["statements"] for x in _wrap(s)]]
    lines += [
        f"Authorised by: {c['authorized_by']}",
        f"Results from external providers: {c['external_providers']}",
    ]
    lines += ["", f"SHA-256 of the JSON content: {sha256}", "", c["end"]]
    return lines


def render_pdf(content: dict[str, Any], sha256: str) -> bytes:
    """The certificate PDF (bytes)."""
    body = certificate_lines(content, sha256)
    pages = [body[i : i + LINES_PER_PAGE] for i in range(0, len(body), LINES_PER_PAGE)] or [[]]
    buf = io.BytesIO()
    meta = {"Title": f"{content['title']} {content['number']}", "Creator": "calbench"}
    with PdfPages(buf, metadata=meta) as pdf:
        for n, page in enumerate(pages, start=1):
            fig = Figure(figsize=A4_IN)
            fig.text(0.08, 0.955, content["title"], fontsize=16, weight="bold", family="DejaVu Sans")
            fig.text(0.92, 0.955, f"No. {content['number']}", fontsize=10, ha="right", family="DejaVu Sans")
            fig.text(0.08, 0.935, content["laboratory"]["name"], fontsize=9, family="DejaVu Sans")
            fig.text(0.92, 0.935, f"page {n} of {len(pages)}", fontsize=9, ha="right", family="DejaVu Sans")
            y = 0.905
            for line in page:
                fig.text(0.06, y, line, fontsize=7.2, family="DejaVu Sans Mono", va="top")
                y -= 0.0148
            pdf.savefig(fig)
    return buf.getvalue()
