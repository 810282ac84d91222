"""Self-contained HTML report of a diagnosis: tables, and inline SVG plots of the window
residuals (normalised, per channel, before and after) and of the regressor correlations."""

from __future__ import annotations

import html

import numpy as np

from api.plots.colours import CHANNEL_COLOURS
from bench.diagnosis.result import Diagnosis

_COLORS = CHANNEL_COLOURS  # x, y, z as on the dashboard and the Allan plot


def _bars_svg(values: np.ndarray, labels: tuple[str, ...], title: str, limit: float = 3.0) -> str:
    """Grouped bars (m windows × 3 channels) of z-scores with ±limit lines."""
    m = values.shape[0]
    w, h, pad = max(420, 36 * m), 220, 30
    top = max(float(np.max(np.abs(values))), limit) * 1.1
    y0 = h / 2
    sy = (h / 2 - pad) / top
    bw = (w - 2 * pad) / (m * 4)
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h + 40}" role="img">',
        f"<title>{html.escape(title)}</title>",
        f'<text x="{pad}" y="14" font-size="12">{html.escape(title)}</text>',
        f'<line x1="{pad}" x2="{w - pad}" y1="{y0}" y2="{y0}" stroke="#000"/>',
    ]
    for s in (limit, -limit):
        yy = y0 - s * sy
        parts.append(
            f'<line x1="{pad}" x2="{w - pad}" y1="{yy:.1f}" y2="{yy:.1f}" stroke="#999" stroke-dasharray="4"/>'
        )
    for k in range(m):
        for i in range(3):
            v = float(values[k, i])
            x = pad + (4 * k + i + 0.5) * bw
            y, hh = (y0 - v * sy, v * sy) if v >= 0 else (y0, -v * sy)
            parts.append(
                f'<rect x="{x:.1f}" y="{y:.1f}" width="{bw:.1f}" height="{hh:.1f}" fill="{_COLORS[i]}"/>'
            )
        parts.append(
            f'<text x="{pad + (4 * k + 1.5) * bw:.1f}" y="{h + 12}" font-size="9" text-anchor="middle">'
            f"{html.escape(labels[k])}</text>"
        )
    parts.append(
        f'<text x="{pad}" y="{h + 32}" font-size="11">z-score (residual / noise sigma); '
        "blue ax, green ay, red az; dashed: ±3</text></svg>"
    )
    return "".join(parts)


def _corr_svg(d: Diagnosis, n: int = 12) -> str:
    rows = list(d.correlations)[:n]
    w, rh = 480, 18
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{rh * len(rows) + 20}" role="img">',
        "<title>correlations</title>",
    ]
    for k, c in enumerate(rows):
        y = 10 + k * rh
        length = abs(c.rho) * 200
        x = 260 if c.rho >= 0 else 260 - length
        col = "#d62728" if c.significant else "#999"
        name = f"{c.regressor} vs {'xyz'[c.channel]}"
        parts.append(f'<text x="0" y="{y + 12}" font-size="11">{html.escape(name)}</text>')
        parts.append(f'<rect x="{x:.1f}" y="{y}" width="{length:.1f}" height="{rh - 4}" fill="{col}"/>')
        parts.append(f'<text x="{470}" y="{y + 12}" font-size="11" text-anchor="end">{c.rho:+.2f}</text>')
    parts.append("</svg>")
    return "".join(parts)


def render(d: Diagnosis) -> str:
    """The report as one HTML string (no external resources)."""
    e = html.escape
    find_rows = (
        "".join(
            f"<tr><td>{e(f.effect)}</td><td>{e(f.summary)}</td><td>{f.delta_bic:.1f}</td>"
            f"<td>{f.residual_rms_after:.3g}</td><td>{e(f.explanation)}</td></tr>"
            for f in d.findings
        )
        or '<tr><td colspan="5">none from the catalogue</td></tr>'
    )
    disc_rows = "".join(
        f"<tr><td>{e(x.channel)}</td><td>{e(x.term)}</td><td>{x.coefficient:.3g} ± {x.sigma:.2g} {e(x.unit)}</td>"
        f"<td>{x.delta_bic:.1f}</td><td>{x.residual_rms_after:.3g}</td><td>{e(x.physics)}</td></tr>"
        for x in d.discovered
    )
    disc = (
        "<h2>Beyond the catalogue</h2><table><tr><th>channel</th><th>term</th><th>coefficient</th>"
        f"<th>ΔBIC</th><th>rms after</th><th>physics</th></tr>{disc_rows}</table>"
        if d.discovered
        else ""
    )
    u = d.unexplained
    verdict = (
        f"<h2>Unexplained</h2><p><b>The final model still fails the recording's noise</b> "
        f"(chi2/dof {u.chi2_dof:.3g}; {e(u.test)}): {e(u.where)}; correlates with "
        f"{e(', '.join(u.correlates_with) or 'nothing significant')}</p>"
        if u is not None
        else "<p>The final model explains the recording to its noise.</p>"
    )
    unobs = "".join(f"<li><b>{e(k)}</b>: {e(v)}</li>" for k, v in d.unobservable.items())
    notes = "".join(f"<li>{e(n)}</li>" for n in d.notes)
    b, f = d.baseline, d.final
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>diagnosis {e(d.unit)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}td,th{{border:1px solid #ccc;padding:4px}}
table{{border-collapse:collapse}}</style></head><body>
<h1>Diagnosis of {e(d.unit)}</h1><p>{e(d.source)}</p>
<table><tr><th>model</th><th>terms</th><th>residual rms ({e(d.channel_unit)})</th><th>chi2/dof</th><th>BIC</th></tr>
<tr><td>first order</td><td>{e(", ".join(b.terms))}</td><td>{b.residual_rms:.3g}</td><td>{b.chi2_dof:.3g}</td><td>{b.bic:.1f}</td></tr>
<tr><td>final</td><td>{e(", ".join(f.terms))}</td><td>{f.residual_rms:.3g}</td><td>{f.chi2_dof:.3g}</td><td>{f.bic:.1f}</td></tr></table>
<h2>Where the first-order model misses</h2><p>{e(d.where)}</p>
{_bars_svg(b.z, d.labels, "residuals before (first-order model)")}
{_bars_svg(f.z, d.labels, "residuals after (final model)")}
<h2>What the residuals correlate with</h2>{_corr_svg(d)}
<h2>Findings</h2><table><tr><th>effect</th><th>summary</th><th>ΔBIC</th><th>rms after</th><th>physics</th></tr>
{find_rows}</table>{disc}{verdict}
<h2>Not observable in this recording</h2><ul>{unobs}</ul><h2>Notes</h2><ul>{notes}</ul></body></html>"""
