"""The certificate as a PDF, rendered from its JSON content with matplotlib's PDF backend.

A4 pages laid out like a laboratory's certificate: a title block on every page (laboratory,
"Calibration Certificate", number, "Page n of N"), tables of the item, the method, the
conditions and the results with their units and expanded uncertainties U = k·u_c (the k of
each quantity in the content: 2 unless the budget has finite degrees of freedom), the |g|
check before and after, the diagnosis findings, the traceability and conformity statements,
the authorisation with a signature line, "End of certificate" (ISO/IEC 17025 7.8.2.1 d), and
in the footer of every page the SHA-256 of the JSON content, so a reader can check the
paper against the stored record. Text only comes from the content, and from the kind of the
fit (:class:`bench.fit_kind.FitKind`, as the stored fit states it:
:attr:`bench.fitted_model.FittedModel.kind`), which says over what the |g| check was taken;
nothing is recomputed.
"""

from __future__ import annotations

import datetime as dt
import io
import math
from typing import Any

from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from bench.fit_kind import FitKind
from station.certificates.pdf_budget import budget_section
from station.certificates.pdf_layout import Flow, Page, wrap
from station.certificates.pdf_record import record_section
from station.certificates.rounding import format_significant, value_and_u

A4_IN = (8.27, 11.69)
AXES = ("x", "y", "z")
FONT = "DejaVu Sans"
G_CHECK_OVER = {
    FitKind.STATIC: "over the static positions",
    FitKind.ORIENTATION_FREE: "over the static positions",
    FitKind.MOVING: "over 1 s blocks of the moving recording, gravity with the fitted motion terms removed",
}
"""Over what each kind of fit takes its |g| check."""


def _unit(text: str) -> str:
    return text.replace("m/s2", "m/s²")


def _when(value: Any) -> str:
    """An ISO 8601 time as ``YYYY-MM-DD HH:MM:SS UTC`` (other text unchanged)."""
    try:
        t = dt.datetime.fromisoformat(str(value))
    except ValueError:
        return _text(value)
    if t.tzinfo is None or len(str(value)) <= 10:
        return _text(value)
    return t.astimezone(dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return "" if value is None else str(value)


def _stat(value: Any) -> str:
    """A statistic the content states to two significant digits, printed with both (2.0e-05)."""
    if isinstance(value, float | int) and not isinstance(value, bool) and math.isfinite(value):
        return format_significant(value)
    return _text(value)


def _identification(f: Flow, c: dict[str, Any]) -> None:
    item, dates, cust = c["item"], c["dates"], c["customer"]
    when = f"{_when(dates['calibration_start'])} to {_when(dates['calibration_end'])}"
    nominal = item.get("nominal_scale", {})
    zero_g = item.get("nominal_zero_g_output", {})
    f.heading("1  Customer and item")
    f.table(
        [
            ("Customer", _text(cust.get("name"))),
            ("Customer address", _text(cust.get("address"))),
            ("Item", f"{item['description']}, model {item['model']}"),
            ("Serial number", _text(item["serial"])),
            ("Output unit", _unit(_text(item["channel_unit"]))),
            (
                "Nominal scale factor",
                f"{_text(nominal.get('value'))} {_unit(_text(nominal.get('unit')))}".strip(),
            ),
            (
                "Nominal zero-g output",
                f"{_text(zero_g.get('value'))} {_unit(_text(zero_g.get('unit')))}".strip(),
            ),
            ("Condition as received", _text(item["condition"])),
            ("Adjustment", _text(item.get("adjustment"))),
            ("Date of receipt", _text(dates["received"])),
            ("Date(s) of calibration", when),
            ("Date of issue", _when(dates["issued"])),
            ("Place of calibration", f"{c['location']}, bench {c.get('bench')}"),
            ("Run identifier", _text(c.get("run_id"))),
            ("Run started by", _text(c.get("run_record", {}).get("started_by", "not stated"))),
        ],
        widths=(0.3, 0.7),
    )


def _software(c: dict[str, Any]) -> str:
    sw = c.get("software")
    return f"{sw['name']} {sw['version']}" if isinstance(sw, dict) else "not stated"


def _method_conditions(f: Flow, c: dict[str, Any]) -> None:
    m, cond = c["method"], c["conditions"]
    given = sorted((k, v) for k, v in m.get("parameters", {}).items() if v is not None)
    params = ", ".join(f"{k} = {_text(v)}" for k, v in given) or "defaults"
    f.heading("2  Method")
    f.table(
        [
            ("Procedure", f"{m['procedure']}: {m['description']}"),
            ("Parameters", params),
            ("Procedure version", _text(m.get("procedure_version", "not stated"))),
            ("Deviations from the method", "; ".join(m["deviations"])),
            ("Sampling", _text(m.get("sampling"))),
            ("Software", _software(c)),
            ("Reference equipment", "; ".join(c.get("reference_equipment", ["not stated"]))),
        ],
        widths=(0.3, 0.7),
    )
    t = cond["sensor_temperature"]
    temp = _text(t)
    if isinstance(t, dict):
        temp = f"{t['mean_c']:.2f} °C (min {t['min_c']:.2f} °C, max {t['max_c']:.2f} °C)"
    g_local = cond["g_local_m_s2"]
    table = cond.get("table")
    if isinstance(table, dict):
        axes = ", ".join(f"{a['name']} about {tuple(a['axis'])}" for a in table.get("axes", []))
        arm = ", ".join(f"{1000 * x:.1f}" for x in table.get("lever_arm_m", []))
        table_text = f"axes {axes}; lever arm ({arm}) mm"
    else:
        table_text = _text(table)
    f.heading("3  Conditions of calibration")
    f.table(
        [
            ("Ambient conditions", _text(cond.get("ambient", "not stated"))),
            ("Sensor temperature", temp),
            ("Local gravity g_local", f"{g_local:.6f} m/s²" if isinstance(g_local, float) else str(g_local)),
            ("Rotary table", table_text),
            ("Sample integrity", _text(cond.get("sample_integrity", "not stated"))),
            ("Bench configuration", _text(cond.get("bench_configuration", "not stated"))),
        ],
        widths=(0.3, 0.7),
    )


def _vu(v: Any, u: Any) -> str:
    return "–" if v is None else " ± ".join(value_and_u(float(v), float(u)))


def _datasheet(f: Flow, d: dict[str, Any] | None) -> None:
    """The same model in data-sheet units: sensitivity, zero-g output, cross-axis (mrad)."""
    if not isinstance(d, dict):
        return
    s, z, x = d["sensitivity"], d["zero_g_output"], d["cross_axis"]
    f.subheading("The same results in data-sheet units, value ± U")
    rows = [
        (
            "Axis",
            f"Sensitivity ({s['unit']})",
            f"Zero-g output ({z['unit']})",
            *(f"Cross-axis from {b} ({x['unit']})" for b in AXES),
        )
    ]
    for i, a in enumerate(AXES):
        rows.append(
            (
                a,
                _vu(s["value"][i], s["expanded_uncertainty"][i]),
                _vu(z["value"][i], z["expanded_uncertainty"][i]),
                *(_vu(x["value"][i][j], x["expanded_uncertainty"][i][j]) for j in range(3)),
            )
        )
    f.table(rows, widths=(0.07, 0.19, 0.19, 0.183, 0.183, 0.184), header=True, align="right", size=7.5)
    f.paragraph(f"Sensitivity: {s['basis']}. Cross-axis: {x['basis']}.", size=7.5)


def _results(f: Flow, c: dict[str, Any], kind: FitKind) -> None:
    res = c["results"]
    f.heading("4  Results")
    f.paragraph(f"Model: {_unit(res['model'])}.  Terms fitted: {', '.join(res['terms'])}.")
    bias = res["bias"]
    rows: list[tuple[str, ...]] = [
        ("Axis", f"Bias ({_unit(bias['unit'])})", f"U, k = {bias['k']:.3g} ({_unit(bias['unit'])})")
    ]
    for a, v, u in zip(AXES, bias["value"], bias["expanded_uncertainty"], strict=True):
        rows.append((a, *value_and_u(v, u)))
    f.subheading("Bias b (zero-g output)")
    f.table(rows, widths=(0.2, 0.4, 0.4), header=True, align="right")
    sm = res["scale_matrix"]
    f.subheading(f"Scale and misalignment matrix K ({_unit(sm['unit'])}), value ± U (k = {sm['k']:.3g})")
    rows = [("output \\ input", "x", "y", "z")]
    for a, vr, ur in zip(AXES, sm["value"], sm["expanded_uncertainty"], strict=True):
        rows.append((a, *(" ± ".join(value_and_u(v, u)) for v, u in zip(vr, ur, strict=True))))
    f.table(rows, widths=(0.16, 0.28, 0.28, 0.28), header=True, align="right")
    _datasheet(f, res.get("datasheet_units"))
    rms = res["residual_rms"]
    f.paragraph(f"Residual RMS of the fit: {_stat(rms['value']) or 'not available'} {_unit(rms['unit'])}.")
    g = c["g_check"]
    f.subheading(f"|g| check: |K⁻¹(raw − b)| − g_local {G_CHECK_OVER[kind]} (m/s²)")
    rows = [("", "mean error", "U of the mean, k = 2", "standard deviation", "n")]
    for when, label in (("before", "with the nominal values"), ("after", "with this calibration")):
        v = g[when]
        rows.append(
            (
                label,
                _stat(v.get("mean_error_m_s2")),
                _stat(v.get("expanded_uncertainty_m_s2")) or "not stated",
                _stat(v.get("std_m_s2")),
                _text(v.get("n")),
            )
            if isinstance(v, dict)
            else (label, _text(v), "", "", "")
        )
    f.table(rows, widths=(0.3, 0.18, 0.2, 0.2, 0.12), header=True, align="right")
    if g.get("uncertainty_basis"):
        f.paragraph(f"U of the mean error: {g['uncertainty_basis']}.", size=7.5)
    if g.get("before_basis"):
        f.paragraph(f"Basis of 'before': {g['before_basis']}.", size=7.5)
    f.paragraph(c["uncertainty_statement"], size=7.5)


def _statements(f: Flow, c: dict[str, Any]) -> None:
    diag = c["diagnosis"]
    f.heading("6  Diagnosis of unmodelled effects (opinion, ISO/IEC 17025 7.8.7)")
    f.paragraph(diag["note"][:1].upper() + diag["note"][1:] + ".")
    if diag["findings"]:
        rows = [("Effect", "Finding")] + [(str(x["effect"]), str(x["summary"])) for x in diag["findings"]]
        f.table(rows, widths=(0.25, 0.75), header=True)
    _conformity(f, c)
    f.heading("8  Traceability, external providers")
    f.table(
        [
            ("Traceability", c["traceability"]),
            ("External providers", _text(c["external_providers"])),
        ],
        widths=(0.22, 0.78),
    )
    for s in c["statements"]:
        f.paragraph(s, size=7.5)
    f.signature(c["authorized_by"], _when(c["dates"]["issued"]), c.get("authorization", ""))
    f.end(c["end"])


def conformity_line(c: dict[str, Any]) -> str:
    """The one line on every page that states the conformity verdict (or that none is made)."""
    conf = c["conformity"]
    if isinstance(conf, str):  # a certificate issued before the statement had its own section
        return f"Conformity: {conf}"
    if not conf.get("requested"):
        return "Conformity: no statement of conformity (no specification limits apply)"
    rule = str(conf.get("rule", "")).replace("-", " ")
    spec = str(conf["specification"]).removeprefix("limits of ")
    return f"Conformity: {conf['outcome']} against the limits of {spec} ({rule})"


def _check_row(r: dict[str, Any]) -> tuple[str, ...]:
    U = r.get("expanded_uncertainty")
    value, u_text = (
        value_and_u(float(r["value"]), float(U))
        if isinstance(U, float | int) and U > 0
        else (f"{float(r['value']):.6g}", "not stated")
    )
    lo, hi = r.get("low"), r.get("high")
    alo, ahi = r.get("acceptance_low"), r.get("acceptance_high")
    tol = f"[{'−∞' if lo is None else f'{lo:.6g}'}, {'+∞' if hi is None else f'{hi:.6g}'}]"
    acc = f"[{'−∞' if alo is None else f'{alo:.6g}'}, {'+∞' if ahi is None else f'{ahi:.6g}'}]"
    return (str(r["quantity"]), value, u_text, _unit(str(r["unit"])), tol, acc, str(r["verdict"]))


def _conformity(f: Flow, c: dict[str, Any]) -> None:
    conf = c["conformity"]
    f.heading("7  Statement of conformity (ISO/IEC 17025 7.8.6)")
    if isinstance(conf, str):
        f.paragraph(conf)
        return
    f.paragraph(conf["statement"], size=9)
    f.paragraph(f"Decision rule: {conf['decision_rule']}.", size=7.5)
    if conf.get("checks"):
        f.paragraph(
            f"Specification: {conf['specification']}. U of the |g| check: {conf['g_check_uncertainty']}.",
            size=7.5,
        )
        rows: list[tuple[str, ...]] = [
            ("Quantity", "Value", "U", "Unit", "Tolerance interval", "Acceptance interval", "Verdict")
        ]
        rows += [_check_row(r) for r in conf["checks"]]
        f.table(rows, widths=(0.15, 0.14, 0.11, 0.10, 0.18, 0.18, 0.14), header=True, size=7)


def _decorate(fig: Figure, page: Page, n: int, total: int, c: dict[str, Any], sha256: str) -> None:
    lab = c["laboratory"]
    fig.text(0.07, 0.962, lab["name"], fontsize=11, weight="bold", family=FONT)
    fig.text(0.07, 0.947, lab["address"], fontsize=7.5, family=FONT, color="0.25")
    fig.text(0.93, 0.962, c["title"], fontsize=13, weight="bold", ha="right", family=FONT)
    fig.text(0.93, 0.947, f"Certificate No. {c['number']}", fontsize=9, ha="right", family=FONT)
    fig.text(0.93, 0.934, f"Page {n} of {total}", fontsize=8, ha="right", family=FONT)
    fig.text(0.07, 0.932, conformity_line(c), fontsize=7.5, weight="bold", family=FONT)
    fig.add_artist(_rule(0.927))
    fig.add_artist(_rule(0.052))
    foot = f"Certificate No. {c['number']}  ·  SHA-256 of the content: {sha256}"
    fig.text(0.07, 0.040, foot, fontsize=6.2, family="DejaVu Sans Mono", color="0.25")
    fig.text(0.07, 0.028, c["statements"][-1], fontsize=6.2, family=FONT, color="0.25")
    fig.text(0.93, 0.028, f"Page {n} of {total}", fontsize=7, ha="right", family=FONT)
    page.draw(fig)


def _rule(y: float) -> Any:
    from matplotlib.lines import Line2D

    return Line2D([0.07, 0.93], [y, y], lw=0.8, color="0.3")


def certificate_pages(c: dict[str, Any], kind: FitKind) -> list[Page]:
    """The laid-out body pages of a certificate of a fit of ``kind``."""
    f = Flow(top=0.915, bottom=0.065, left=0.07, right=0.93)
    _identification(f, c)
    _method_conditions(f, c)
    record_section(f, c)
    _results(f, c, kind)
    budget_section(f, c)
    _statements(f, c)
    return f.pages


def certificate_lines(c: dict[str, Any], sha256: str, *, kind: FitKind) -> list[str]:
    """The text of the certificate of a fit of ``kind``, line by line (for a text rendering or
    a search)."""
    lines = [c["title"], c["number"], c["laboratory"]["name"]]
    for page in certificate_pages(c, kind):
        lines += page.texts()
    return [*lines, f"SHA-256 of the content: {sha256}"]


def render_pdf(content: dict[str, Any], sha256: str, *, kind: FitKind) -> bytes:
    """The PDF (bytes) of the certificate of a fit of ``kind``."""
    pages = certificate_pages(content, kind)
    buf = io.BytesIO()
    meta = {"Title": f"{content['title']} {content['number']}", "Creator": "calbench", "Subject": sha256}
    with PdfPages(buf, metadata=meta) as pdf:
        for n, page in enumerate(pages, start=1):
            fig = Figure(figsize=A4_IN)
            _decorate(fig, page, n, len(pages), content, sha256)
            pdf.savefig(fig)
    return buf.getvalue()


__all__ = ["G_CHECK_OVER", "certificate_lines", "render_pdf", "value_and_u", "wrap"]
