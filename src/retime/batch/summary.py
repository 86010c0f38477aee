"""OUTDIR/summary.csv (one row per clip) and OUTDIR/index.html (the same table, sortable, with each
clip's timing curve as a small inline SVG). Both are read back from the clips' own outputs."""
from __future__ import annotations

import csv
import html
import io
import json
import os
from pathlib import Path
from urllib.parse import quote

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


SHOWN_SPEEDS = 3  # flight speeds listed in a cell; more are summarised (a cell of 12 pushed the curves off-screen)


def speeds_cell(text: str) -> tuple[str, str]:
    """(what the page shows, its tooltip) for a row's ``a;b;c`` flight speeds."""
    speeds = [float(v) for v in text.split(";") if v]
    if len(speeds) <= SHOWN_SPEEDS:
        return ", ".join(f"{v:.3g}" for v in speeds), ""
    return (f"{len(speeds)} flights: {min(speeds):.3g}-{max(speeds):.3g} (median {sorted(speeds)[len(speeds) // 2]:.3g})",
            ", ".join(f"{v:.3g}" for v in speeds))


def row_warning(row: dict, points=None) -> str:
    """What the command line said about a clip, for its row: a duration below its least physical one by more
    than half an output frame (``points``: its warp, a row per output frame)."""
    try:
        duration, least = float(row["output_duration"]), float(row["least_duration"])
    except (KeyError, ValueError):
        return ""
    half_frame = 0.5 * duration / (len(points) - 1) if points and len(points) > 1 else 0.0
    if duration >= least - half_frame:
        return ""
    feasible = f"; {float(row['feasible_fraction']):.0%} of frames feasible" if row.get("feasible_fraction") else ""
    return f"below its least physical duration {least:.3f} s{feasible}"


def _caption(method: str | None, timing: bool, plots: bool) -> str:
    if method == "check":
        return ("Ranked from least to most physical as captured: source physical is the verdict of retime check, "
                "off share the share of frames the clip's own timing cannot carry. "
                + ("Each plot opens at full size. " if plots else "") + "Click a column to sort.")
    return "Click a column to sort." + (" Timing: source time against output time; dashed, the uniform timing."
                                        if timing else "")


def write_index_html(rows: list[dict], curves: list, path: Path, title: str, method: str | None = None,
                     plots: list | None = None) -> None:
    """A self-contained page: no network, a few lines of script to sort by any column. Columns no clip fills
    are left out; ``plots``: each clip's plot image (``retime check --plot``), linked with a thumbnail."""
    e = html.escape
    columns = [c for c in COLUMNS if c in ("input", "status") or any(str(r[c]) for r in rows)]
    timing = any(curves)
    plots = [p if p is not None and Path(p).is_file() else None for p in (plots or [None] * len(rows))]
    show_plots = any(plots)
    head = "".join(f"<th>{e(c.replace('_', ' '))}</th>" for c in columns) + ("<th>timing</th>" if timing else "") \
        + ("<th>plot</th>" if show_plots else "")
    warnings = [row_warning(row, points) for row, points in zip(rows, curves)]
    body = []
    for row, points, plot, warning in zip(rows, curves, plots, warnings):
        cells = []
        for c in columns:
            text, tip = speeds_cell(str(row[c])) if c == "flight_speeds" else (str(row[c]), "")
            more = f'<div class="warning">{e(warning)}</div>' if c == "status" and warning else ""
            tooltip = f' title="{e(tip)}"' if tip else ""
            cells.append(f"<td{tooltip}>{e(text)}{more}</td>")
        if timing:
            cells.append(f"<td>{curve_svg(points)}</td>")
        if show_plots:
            href = e(quote(Path(os.path.relpath(plot, path.parent)).as_posix())) if plot else ""
            cells.append(f'<td><a href="{href}"><img src="{href}" alt="check plot" width="180" loading="lazy"></a></td>'
                         if plot else "<td></td>")
        body.append(f'<tr class="{e(row["status"])}{" warn" if warning else ""}">{"".join(cells)}</tr>')
    counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped", "failed")}
    warned = sum(bool(w) for w in warnings)
    tally = f"{counts['done']} done, {counts['skipped']} skipped, {counts['failed']} failed" \
        + (f", {warned} with a warning" if warned else "")
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>
<style>
body{{font:14px system-ui,sans-serif;margin:1.5em}} table{{border-collapse:collapse}}
th,td{{border:1px solid #ddd;padding:3px 6px;text-align:left;vertical-align:middle}}
th{{cursor:pointer;background:#f4f4f4;user-select:none}} tr.failed td{{background:#fff0f0}}
tr.skipped td{{color:#666}} tr.warn td{{background:#fff8e1}} .warning{{color:#9a6700;font-size:12px;max-width:22em}}
td img{{display:block}}
</style></head><body>
<h1>{e(title)}</h1>
<p>{len(rows)} clips: {tally}.
{e(_caption(method, timing, show_plots))}</p>
<table><thead><tr>{head}</tr></thead><tbody>
{chr(10).join(body)}
</tbody></table>
<script>{_SCRIPT}</script>
</body></html>
"""
    with atomic_write(path) as f:
        f.write(page)
