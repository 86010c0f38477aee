"""OUTDIR/summary.csv (one row per clip) and OUTDIR/index.html (the same table, sortable, with each
clip's timing curve as a small inline SVG). Both are read back from the clips' own outputs."""
from __future__ import annotations

import csv
import html
import io
import json
from pathlib import Path

from ..io_util import atomic_write

COLUMNS = ("input", "status", "error", "source_duration", "output_duration", "flight_speeds",
           "feasible_fraction", "least_duration", "source_physical", "off_share", "seconds")


def clip_row(input_text: str, status: str, error: str, seconds: float | None, outputs: dict[str, Path],
             curve=None) -> dict:
    """A summary row; durations and physics figures come from the clip's warp (``curve``, the rows
    :func:`read_warp` read) and its report."""
    row = dict.fromkeys(COLUMNS, "")
    row.update(input=input_text, status=status, error=error, seconds="" if seconds is None else f"{seconds:.2f}")
    if status == "failed":
        return row
    if curve is not None:
        row["output_duration"], row["source_duration"] = f"{curve[-1][0]:.6g}", f"{curve[-1][1]:.6g}"
    if "report" in outputs:
        try:
            summary = json.loads(outputs["report"].read_text(encoding="utf-8"))["summary"]
        except (OSError, ValueError, KeyError, TypeError):
            return row
        if "physical" in summary:  # a check report (retime check): the verdict and its share of bad frames
            row.update(source_physical=_flag(summary.get("physical")), off_share=_number(summary.get("off_share")),
                       flight_speeds="")
            return row
        flights = [p.get("speed") for p in summary.get("phases", []) if p.get("state") == "flight"]
        row.update(
            source_duration=_number(summary.get("source_duration")) or row["source_duration"],
            output_duration=_number(summary.get("duration")) or row["output_duration"],
            flight_speeds=";".join(_number(s) for s in flights if s is not None),
            feasible_fraction=_number(summary.get("feasible_fraction")),
            least_duration=_number(summary.get("least_duration")),
            source_physical=_flag((summary.get("source_check") or {}).get("physical")),
            off_share=_number((summary.get("source_check") or {}).get("off_share")))
    return row


def _number(value) -> str:
    return "" if value is None or isinstance(value, bool) else f"{value:.6g}"


def _flag(value) -> str:
    return "" if value is None else str(bool(value)).lower()


def read_warp(path: Path) -> list[tuple[float, float]] | None:
    """(output_time, source_time) rows of a warp CSV, or None when it is missing or unreadable."""
    from ..warp import TimingCurve

    try:
        curve = TimingCurve.from_csv(path)
    except Exception:  # a summary describes what is there; a broken warp file just has no curve
        return None
    return list(zip(curve.t.tolist(), curve.s.tolist()))


def write_summary_csv(rows: list[dict], path: Path) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_write(path, newline="") as f:
        f.write(buffer.getvalue())


def curve_svg(points: list[tuple[float, float]] | None, width=120, height=48) -> str:
    """Source time (up) against output time (right); the dashed line is the uniform timing."""
    if not points or points[-1][0] <= 0 or points[-1][1] <= 0:
        return ""
    step = max(1, len(points) // 200)  # a few hundred vertices are plenty at this size
    kept = points[::step] + ([points[-1]] if (len(points) - 1) % step else [])
    t_end, s_end = points[-1]
    xy = " ".join(f"{t / t_end * width:.1f},{height - s / s_end * height:.1f}" for t, s in kept)
    return (f'<svg width="{width}" height="{height}" viewBox="0 0 {width} {height}" role="img" '
            f'aria-label="timing curve"><line x1="0" y1="{height}" x2="{width}" y2="0" stroke="#bbb" '
            f'stroke-dasharray="3,3"/><polyline fill="none" stroke="#1f6feb" stroke-width="1.5" points="{xy}"/></svg>')


_SCRIPT = """
document.querySelectorAll('th').forEach((th, col) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], up = th.dataset.dir !== 'up';
  th.dataset.dir = up ? 'up' : 'down';
  const key = r => { const t = r.cells[col].textContent.trim(), n = parseFloat(t);
                     return t !== '' && !isNaN(n) && isFinite(t) ? n : t.toLowerCase(); };
  [...body.rows].sort((a, b) => { const x = key(a), y = key(b);
    if (typeof x !== typeof y) return (typeof x === 'number' ? -1 : 1) * (up ? 1 : -1);
    return (x < y ? -1 : x > y ? 1 : 0) * (up ? 1 : -1); }).forEach(r => body.appendChild(r));
}));
"""


def write_index_html(rows: list[dict], curves: list, path: Path, title: str) -> None:
    """A self-contained page: no network, a few lines of script to sort by any column."""
    e = html.escape
    head = "".join(f"<th>{e(c.replace('_', ' '))}</th>" for c in COLUMNS) + "<th>timing</th>"
    body = []
    for row, points in zip(rows, curves):
        cells = "".join(f"<td>{e(str(row[c]))}</td>" for c in COLUMNS)
        body.append(f'<tr class="{e(row["status"])}">{cells}<td>{curve_svg(points)}</td></tr>')
    counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped", "failed")}
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>
<style>
body{{font:14px system-ui,sans-serif;margin:1.5em}} table{{border-collapse:collapse}}
th,td{{border:1px solid #ddd;padding:3px 6px;text-align:left;vertical-align:middle}}
th{{cursor:pointer;background:#f4f4f4;user-select:none}} tr.failed td{{background:#fff0f0}}
tr.skipped td{{color:#666}}
</style></head><body>
<h1>{e(title)}</h1>
<p>{len(rows)} clips: {counts['done']} done, {counts['skipped']} skipped, {counts['failed']} failed.
Click a column to sort. Timing: source time against output time; dashed, the uniform timing.</p>
<table><thead><tr>{head}</tr></thead><tbody>
{chr(10).join(body)}
</tbody></table>
<script>{_SCRIPT}</script>
</body></html>
"""
    with atomic_write(path) as f:
        f.write(page)
