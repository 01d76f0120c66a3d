"""index.html: every run's figures and metrics on one page."""

from __future__ import annotations

import html
import math
from pathlib import Path

LABELS = [
    ("time_to_1mm_s", "time to 1 mm [s]", 1.0, "{:.3f}"),
    ("dist_rms_after_m", "RMS distance after [mm]", 1e3, "{:.3f}"),
    ("dist_max_after_m", "max distance after [mm]", 1e3, "{:.3f}"),
    ("force_max_n", "max force [N]", 1.0, "{:.2f}"),
    ("force_rms_n", "RMS force [N]", 1.0, "{:.2f}"),
    ("passive_torque_max", "max passive torque [N·m]", 1.0, "{:.3g}"),
    ("torque_fraction_max", "max torque / limit", 1.0, "{:.2f}"),
    ("energy_to_user_j", "energy to user [mJ]", 1e3, "{:.2f}"),
    ("real_time_factor", "× real time", 1.0, "{:.1f}"),
]


def _fmt(v, scale, fmt):
    if v is None or (isinstance(v, float) and math.isnan(v)) or isinstance(v, str):
        return "–"
    return fmt.format(v * scale)


def write_index(out_dir: str | Path, entries: list[dict], title: str = "virtmech demo") -> Path:
    """entries: [{"name", "description", "dir" (relative), "metrics"}]."""
    out = Path(out_dir)
    head = "".join(f"<th>{html.escape(lbl)}</th>" for _, lbl, _, _ in LABELS)
    rows = []
    for e in entries:
        m = e["metrics"]
        cells = "".join(f"<td>{_fmt(m.get(k), s, f)}</td>" for k, _, s, f in LABELS)
        rows.append(f'<tr><td><a href="#{e["name"]}">{html.escape(e["name"])}</a></td>{cells}</tr>')
    sections = []
    for e in entries:
        d = html.escape(e["dir"])
        sections.append(
            f'<section id="{html.escape(e["name"])}"><h2>{html.escape(e["name"])}</h2>'
            f"<p>{html.escape(e['description'])}</p>"
            f'<p><a href="{d}/log.csv">log.csv</a> · <a href="{d}/run.json">run.json</a></p>'
            f'<div class="figs"><img src="{d}/plane.png" alt="{d} plane">'
            f'<img src="{d}/time.png" alt="{d} time"></div>'
            "</section>"
        )
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; max-width: 1500px; }}
table {{ border-collapse: collapse; font-size: 0.9em; }}
td, th {{ border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: right; }}
td:first-child {{ text-align: left; }}
.figs img {{ max-width: 49%; vertical-align: top; }}
section {{ margin-top: 2.5em; border-top: 1px solid #ddd; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p>The paper's Figs. 9–12 (Luecke &amp; Beckman, virtual mechanisms for under-actuated haptic
devices) simulated in MuJoCo on the PHANTOM Omni and on the Planar3R. Metrics: summary.json.</p>
<table><tr><th>scenario</th>{head}</tr>
{"".join(rows)}
</table>
{"".join(sections)}
</body></html>
"""
    path = out / "index.html"
    path.write_text(page, encoding="utf-8")
    return path
