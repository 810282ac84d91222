"""Self-contained HTML report of a diagnosis: tables, and inline SVG plots of the window
residuals (normalised, per channel, before and after: :mod:`api.reports.residual_plot`) and
of the regressor correlations (:mod:`api.reports.correlation_plot`)."""

from __future__ import annotations

import html

from api.reports.correlation_plot import correlation_figure
from api.reports.residual_plot import residual_figure
from bench.diagnosis.result import Diagnosis

STYLE = (
    "body{font-family:sans-serif;max-width:1000px;margin:auto;padding:0 12px}"
    "td,th{border:1px solid #ccc;padding:4px}table{border-collapse:collapse}"
    "figure{margin:12px 0}figure svg{display:block;max-width:100%;height:auto}"
    "figcaption{font-size:13px;color:#444}"
)
"""Page width ≤ 1000 px; plots shrink with a narrower window (viewBox, max-width)."""


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
<meta name="viewport" content="width=device-width, initial-scale=1"><style>{STYLE}</style></head><body>
<h1>Diagnosis of {e(d.unit)}</h1><p>{e(d.source)}</p>
<table><tr><th>model</th><th>terms</th><th>residual rms ({e(d.channel_unit)})</th><th>chi2/dof</th><th>BIC</th></tr>
<tr><td>first order</td><td>{e(", ".join(b.terms))}</td><td>{b.residual_rms:.3g}</td><td>{b.chi2_dof:.3g}</td><td>{b.bic:.1f}</td></tr>
<tr><td>final</td><td>{e(", ".join(f.terms))}</td><td>{f.residual_rms:.3g}</td><td>{f.chi2_dof:.3g}</td><td>{f.bic:.1f}</td></tr></table>
<h2>Where the first-order model misses</h2><p>{e(d.where)}</p>
{residual_figure(b.z, d.mid_s, d.labels, "residuals before (first-order model)")}
{residual_figure(f.z, d.mid_s, d.labels, "residuals after (final model)")}
<h2>What the residuals correlate with</h2>{correlation_figure(d.correlations)}
<h2>Findings</h2><table><tr><th>effect</th><th>summary</th><th>ΔBIC</th><th>rms after</th><th>physics</th></tr>
{find_rows}</table>{disc}{verdict}
<h2>Not observable in this recording</h2><ul>{unobs}</ul><h2>Notes</h2><ul>{notes}</ul></body></html>"""
