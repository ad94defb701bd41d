"""index.html: the report on one page (result, pictures, step table, per-slot cycles,
plots), self-contained apart from the PNGs beside it; no script, no network."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from cellrunner.report.slots import SlotCycle, worst

_STYLE = """
body{font-family:system-ui,sans-serif;margin:24px;max-width:1400px;color:#222}
h1{font-size:22px;margin-bottom:4px} h2{font-size:17px;margin-top:28px;border-bottom:1px solid #ddd}
.ok{color:#1a7f37;font-weight:bold} .bad{color:#cf222e;font-weight:bold}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ddd;padding:3px 8px;text-align:right}
th{background:#f4f4f4} td.l,th.l{text-align:left} tr.worst td{background:#ffe5e5}
img{max-width:100%;border:1px solid #eee;margin:6px 0} .pics{display:flex;flex-wrap:wrap;gap:12px}
.pics figure{margin:0;flex:1 1 560px} figcaption{font-size:12px;color:#555} .muted{color:#777;font-size:12px}
"""


def _e(value: object) -> str:
    return html.escape(str(value))


def write_index(
    folder: Path,
    payload: dict[str, Any],
    step_rows: list[dict[str, Any]],
    views: list[tuple[str, str]],
    plots: list[tuple[str, str]],
    slots: tuple[str, list[SlotCycle]] | None,
    notes: list[str],
) -> Path:
    """Write ``folder/index.html``. ``step_rows``: dicts with index, kind, name,
    planned_s, duration_s, status, attempts, message; ``views``/``plots``: (file, caption)."""
    ok = payload.get("ok")
    verdict = f"<span class='{'ok' if ok else 'bad'}'>{_e(payload.get('result_code'))} {_e(payload.get('result_text'))}</span>"
    params = ", ".join(f"{k}={v}" for k, v in (payload.get("params") or {}).items()) or "none"
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>dry-run {_e(payload.get('task'))}</title>",
        f"<style>{_STYLE}</style></head><body>",
        f"<h1>dry-run {_e(payload.get('task'))} on {_e(payload.get('cell'))}</h1>",
        f"<p>params: {_e(params)} &middot; result {verdict} &middot; cycle {payload.get('cycle_time_s', 0):.2f} s "
        f"simulated vs {payload.get('planned_cycle_time_s', 0):.2f} s planned &middot; max tracking error "
        f"{payload.get('max_tracking_error_m', 0) * 1000:.2f} mm &middot; retries {_e(payload.get('retries', 0))}</p>",
    ]
    if payload.get("injected"):
        parts.append(f"<p>injected faults: {_e(', '.join(payload['injected']))}</p>")
    for note in notes:
        parts.append(f"<p class='muted'>{_e(note)}</p>")
    if views:
        parts.append("<h2>The cell</h2><div class='pics'>")
        parts += [
            f"<figure><img src='{_e(f)}' alt='{_e(c)}'><figcaption>{_e(c)}</figcaption></figure>"
            for f, c in views
        ]
        parts.append("</div>")
    parts.append(
        "<h2>Steps</h2><table><tr><th>#</th><th class='l'>kind</th><th class='l'>name</th>"
        "<th>planned s</th><th>simulated s</th><th class='l'>status</th><th>attempts</th>"
        "<th class='l'>message</th></tr>"
    )
    for r in step_rows:
        parts.append(
            f"<tr><td>{r['index']}</td><td class='l'>{_e(r['kind'])}</td><td class='l'>{_e(r['name'])}</td>"
            f"<td>{r['planned_s']:.2f}</td><td>{r['duration_s']:.2f}</td><td class='l'>{_e(r['status'])}</td>"
            f"<td>{r['attempts']}</td><td class='l'>{_e(r['message'])}</td></tr>"
        )
    parts.append("</table>")
    if slots is not None:
        parts.append(_slots_table(*slots, step_rows))
    if plots:
        parts.append("<h2>Plots</h2>")
        parts += [
            f"<figure><img src='{_e(f)}' alt='{_e(c)}'><figcaption>{_e(c)}</figcaption></figure>"
            for f, c in plots
        ]
    parts.append(
        "<p class='muted'>files: result.json (the --json object), slots.csv, the PNGs above</p></body></html>"
    )
    path = folder / "index.html"
    path.write_text("\n".join(parts), encoding="utf-8")
    return path


def _slots_table(param: str, rows: list[SlotCycle], step_rows: list[dict[str, Any]]) -> str:
    worst_row = worst(rows)
    motion = [
        r
        for r in step_rows
        if r["kind"] in ("move", "approach", "descend", "lift", "retreat", "linear")
    ]
    head = "".join(f"<th>{r['index']} {_e(r['kind'])}</th>" for r in motion)
    out = [
        f"<h2>Planned cycle per {_e(param)}</h2>",
        f"<p>worst: {_e(param)}={worst_row.slot} at {worst_row.cycle_s:.2f} s</p>"
        if worst_row
        else "<p class='bad'>no feasible slot</p>",
        f"<table><tr><th>{_e(param)}</th><th>cycle s</th>{head}<th class='l'>problem</th></tr>",
    ]
    for r in rows:
        cls = " class='worst'" if worst_row is not None and r.slot == worst_row.slot else ""
        cycle = f"{r.cycle_s:.2f}" if r.cycle_s is not None else "infeasible"
        cells = "".join(f"<td>{r.steps_s.get(s['index'], 0.0):.2f}</td>" for s in motion)
        out.append(
            f"<tr{cls}><td>{r.slot}</td><td>{cycle}</td>{cells}<td class='l'>{_e(r.error)}</td></tr>"
        )
    out.append("</table>")
    return "\n".join(out)
