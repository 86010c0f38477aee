"""The demo's HTML report: one self-contained page (inline CSS, no scripts, no external fetches)
whose images, video and downloads are relative links to files beside it."""

from __future__ import annotations

import html
import math
import shlex
from urllib.parse import quote

from retime.io_util import atomic_write

CSS = """
:root { --ink:#1f2933; --muted:#616e7c; --line:#e4e7eb; --bg:#f7f8fa; --card:#ffffff;
        --linear:#d6604d; --guided:#4393c3; --physics:#4da36a; --original:#46566e; --good:#2f7d4f; --bad:#b83227; }
* { box-sizing: border-box; }
html { background: var(--bg); }
body { margin: 0; color: var(--ink); font: 15px/1.55 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
main { max-width: 1120px; margin: 0 auto; padding: 32px 24px 48px; }
header h1 { font-size: 28px; line-height: 1.2; margin: 0 0 6px; letter-spacing: -0.01em; }
header .lead { color: var(--muted); margin: 0; font-size: 16px; }
section { background: var(--card); border: 1px solid var(--line); border-radius: 10px; padding: 20px 24px; margin-top: 20px; }
h2 { font-size: 18px; margin: 0 0 12px; }
dl.facts { display: grid; grid-template-columns: max-content 1fr; gap: 6px 20px; margin: 0; }
dl.facts dt { color: var(--muted); }
dl.facts dd { margin: 0; }
code, pre { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, "DejaVu Sans Mono", monospace; font-size: 13px; }
pre { background: #f3f4f6; border-radius: 6px; padding: 10px 12px; overflow-x: auto; margin: 8px 0 0; }
pre.commands { white-space: pre-wrap; overflow-wrap: anywhere; }
pre.commands span { display: block; padding-left: 2em; text-indent: -2em; }  /* wrapped lines hang */
video, img.plot { display: block; width: 100%; height: auto; border-radius: 6px; border: 1px solid var(--line); background: #fff; }
.caption { color: var(--muted); font-size: 13px; margin: 8px 0 0; }
table { width: 100%; border-collapse: collapse; font-variant-numeric: tabular-nums; }
th, td { text-align: right; padding: 8px 10px; border-bottom: 1px solid var(--line); white-space: nowrap; }
th:first-child, td:first-child { text-align: left; }
th { font-weight: 600; color: var(--muted); font-size: 13px; }
td.files { text-align: left; white-space: normal; }
.swatch { display: inline-block; width: 10px; height: 10px; border-radius: 2px; margin-right: 8px; vertical-align: baseline; }
.badge { display: inline-block; padding: 1px 8px; border-radius: 999px; font-size: 12px; font-weight: 600; }
.badge.good { background: #e3f2e8; color: var(--good); }
.badge.bad { background: #fbe6e3; color: var(--bad); }
.note { color: var(--muted); font-size: 13px; }
.error { color: var(--bad); }
a { color: #2563eb; text-decoration: none; }
a:hover { text-decoration: underline; }
footer { color: var(--muted); font-size: 12px; margin-top: 24px; }
"""

COLORS = {"original": "var(--original)", "linear": "var(--linear)", "guided": "var(--guided)", "physics": "var(--physics)"}
DESCRIPTIONS = {
    "linear": "plays every part of the clip uniformly faster, as spline-based tools do.",
    "guided": "guided time warping (Hsu et al. 2007): keeps local velocities and accelerations close to the input's own.",
    "physics": "physics-based retiming (McCann et al. 2006): keeps contact forces and torques plausible.",
}


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _href(name: str) -> str:
    return quote(name)


def _num(value, fmt: str, dash: str = "&ndash;") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return dash
    return format(value, fmt)


def _speed_badge(speed) -> str:
    if speed is None:
        return "&ndash;"
    good = 0.8 <= speed <= 1.3
    return f'<span class="badge {"good" if good else "bad"}">{speed:.2f}x</span>'


def write_report(result, scale: float, video_fps: float) -> None:
    """Write ``result.out_dir / 'report.html'``."""
    from retime import __version__

    r = result
    stem = r.clip.rsplit(".", 1)[0]
    files = r.files
    parts: list[str] = []
    add = parts.append
    add("<!doctype html>")
    add('<html lang="en"><head><meta charset="utf-8">')
    add('<meta name="viewport" content="width=device-width, initial-scale=1">')
    add(f"<title>retime demo: {_e(stem)} at {scale:g}x duration</title>")
    add(f"<style>{CSS}</style></head><body><main>")

    add("<header>")
    add(f"<h1>Retiming {'CMU ' if r.bundled else ''}{_e(stem)} to {_e(f'{r.duration:.2f}')} s</h1>")
    add(f'<p class="lead">A {_e(f"{r.source_duration:.2f}")} s motion-capture clip played in '
        f"{_e(f'{r.duration:.2f}')} s ({_e(f'{100 * r.duration / r.source_duration:.0f}')}% of its length) by "
        f"{len(r.methods)} methods. Timing is judged by eye: watch the jump's flight beside the original.</p>")
    flights = [(m.name, m.flight_speed) for m in r.methods if m.flight_speed is not None]
    if flights and r.flight:
        add('<p class="lead">The airborne part of the jump plays at '
            + ", ".join(f"<strong>{f:.2f}x</strong> with {_e(n)}" for n, f in flights)
            + " (1x is its natural speed).</p>")
    add("</header>")

    # what was asked
    add('<section id="asked"><h2>What was asked</h2><dl class="facts">')
    part = f"frames {r.frame_range[0]} to {r.frame_range[1]}: " if r.frame_range else ""
    add(f"<dt>clip</dt><dd><code>{_e(r.clip)}</code> ({'CMU ' if r.bundled else ''}motion capture, {part}{r.n_frames} frames at {r.fps:g} Hz, "
        f"{r.source_duration:.3f} s)</dd>")
    add(f"<dt>target duration</dt><dd>{r.duration:.3f} s (scale {scale:g}, rounded to whole frames at {r.fps:g} Hz)</dd>")
    if r.flight:
        add(f"<dt>flight phase</dt><dd>source {r.flight[0]:.3f} s to {r.flight[1]:.3f} s "
            f"({r.flight[1] - r.flight[0]:.3f} s with both feet off the ground)</dd>")
    else:
        add("<dt>flight phase</dt><dd>none detected</dd>")
    for m in r.methods:
        desc = DESCRIPTIONS.get(m.name, "")
        detail = f" <span class='note'>({_e(m.settings)})</span>" if m.settings else ""
        add(f"<dt>{_e(m.name)}</dt><dd>{_e(desc)}{detail}</dd>")
    add("</dl>")
    # the clip where it is (a bundled clip inside the installed package), the outputs beside this report
    clip_arg = shlex.quote(str(r.clip_path.resolve())) if r.clip_path is not None else shlex.quote(r.clip)
    cmds = [f"cd {shlex.quote(str(r.out_dir.resolve()))}"]
    for m in r.methods:
        if m.files:
            cmd = f"retime {m.name} {clip_arg} --duration {r.duration:.4f} -o {m.files['bvh']} --warp {m.files['warp']}"
            if m.name == "linear":
                cmd = f"retime linear {clip_arg} --duration {r.duration:.4f} -o {m.files['bvh']} --warp {m.files['warp']}"
            if m.files.get("report"):
                cmd += f" --report {m.files['report']}"
            cmds.append(cmd)
    warps = " ".join(f"--warp {m.files['warp']}" for m in r.methods if m.files)
    cmds.append(f"retime render {clip_arg} {warps} -o compare.mp4")
    cmds.append(f"retime plot {' '.join(m.files['warp'] for m in r.methods if m.files)} -o timing.png")
    if r.frame_range:
        cmds.insert(1, f"# the demo used source frames {r.frame_range[0]} to {r.frame_range[1]} of the clip")
    add('<p class="note" style="margin-top:12px">The same from the command line:</p>')
    add('<pre class="commands">' + "".join(f"<span>{_e(c)}</span>" for c in cmds) + "</pre>")
    add("</section>")

    # video
    if files.get("video"):
        add('<section id="video"><h2>Side by side</h2>')
        add(f'<video controls loop muted playsinline preload="metadata" poster="{_href(files["poster"])}">'
            f'<source src="{_href(files["video"])}" type="video/mp4">'
            f'<img class="plot" src="{_href(files["poster"])}" alt="still frame of the four motions"></video>')
        add(f'<p class="caption">Original and retimed motions in sync ({_e(files.get("video_size", ""))}, '
            f"{video_fps:g} fps, {_e(files.get('video_frames', ''))} frames; "
            f'<a href="{_href(files["video"])}">compare.mp4</a>). Each panel shows its clock, its playback speed and, '
            "under it, its speed over time on a log scale (0.1x to 10x). The retimed panels end earlier and hold "
            "their last pose.</p>")
        add("</section>")

    # numbers
    add('<section id="numbers"><h2>Numbers</h2><table><thead><tr>'
        "<th>method</th><th>duration</th><th>frames</th><th>mean speed</th><th>flight speed</th>"
        "<th>feasible fraction</th><th>run time</th><th class='files' style='text-align:left'>files</th></tr></thead><tbody>")
    flight_src = (r.flight[1] - r.flight[0]) if r.flight else None
    add(f'<tr><td><span class="swatch" style="background:{COLORS["original"]}"></span>original</td>'
        f"<td>{r.source_duration:.3f} s</td><td>{r.n_frames}</td><td>1.00x</td>"
        f"<td>{_speed_badge(1.0) if flight_src else '&ndash;'}</td><td>&ndash;</td><td>&ndash;</td>"
        f'<td class="files"><code>{_e(r.clip)}</code></td></tr>')
    for m in r.methods:
        sw = f'<span class="swatch" style="background:{COLORS.get(m.name, "#888")}"></span>{_e(m.name)}'
        if m.curve is None:
            add(f'<tr><td>{sw}</td><td colspan="7" class="files error">not run: {_e(m.error or "unavailable")}</td></tr>')
            continue
        links = " &middot; ".join(f'<a href="{_href(v)}">{_e(k)}</a>' for k, v in m.files.items())
        add(f"<tr><td>{sw}</td><td>{m.curve.duration:.3f} s</td><td>{m.motion.n_frames}</td>"
            f"<td>{m.curve.source_duration / m.curve.duration:.2f}x</td>"
            f"<td>{_speed_badge(m.flight_speed)}</td><td>{_num(m.feasible_fraction, '.3f')}</td>"
            f"<td>{_num(m.seconds, '.3f')} s</td><td class='files'>{links}</td></tr>")
    add("</tbody></table>")
    add('<p class="note">Flight speed: source time spent in the flight phase divided by the output time it takes '
        "(1.00x = the jump's airborne part plays at its natural speed; green within 0.8x to 1.3x). "
        "Feasible fraction: share of output frames whose timing lies in the physics feasible region "
        "(from the physics method's report). Run time: computing the timing curve on this machine.</p>")
    add("</section>")

    # plots
    if files.get("timing"):
        add('<section id="curves"><h2>Timing curves and playback speed</h2>')
        add(f'<img class="plot" src="{_href(files["timing"])}" alt="timing curves and playback speed on a log scale">')
        add('<p class="caption">Left: source time p(t) against output time, with the identity. Right: playback speed '
            "dp/dt on a log scale with the 1x line and the tenfold fast-forward and slow-motion limits (as in Hsu et "
            f'al., Fig. 5). <a href="{_href(files["timing_svg"])}">SVG</a></p>')
        add("</section>")
    if files.get("contacts") or files.get("region"):
        add('<section id="physics"><h2>Physics: contacts, feasibility and one frame\'s region</h2>')
        if files.get("contacts"):
            add(f'<img class="plot" src="{_href(files["contacts"])}" alt="contact states and feasibility per frame">')
            add('<p class="caption">Per output frame of the physics result: which heel and toe touch the ground, '
                "and whether the chosen timing lies in its feasible region.</p>")
        if files.get("region"):
            add(f'<img class="plot" src="{_href(files["region"])}" alt="feasible region of one frame" style="margin-top:16px">')
            src = files.get("region_source_frame")
            add(f'<p class="caption">Output frame {_e(files["region_frame"])}'
                + (f" (source frame {_e(src)}; McCann et al. show frame 143 of 16_06 in Fig. 6)" if src else "")
                + ": the feasible region in the (p'', p'^2) plane, the original timing (0, 1) and the chosen "
                "timing, over the magnitude of the objective (Eq. 14 as retime uses it: an exact penalty of the "
                "residual force beyond the region plus the torque term; McCann et al., Fig. 4 and 6). Below: per output frame, which heel and toe "
                "touch the ground and whether the chosen timing lies in its region.</p>")
        add("</section>")

    add("<footer>")
    add(f"Written by retime {_e(__version__)} in {r.total_seconds:.1f} s"
        + (f" (video rendered and encoded at {r.render_fps:.0f} frames/s)" if r.render_fps else "")
        + (". Motion data from the CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu), created with "
           "funding from NSF EIA-0196217." if r.bundled else "."))
    add("</footer></main></body></html>")
    with atomic_write(r.out_dir / "report.html", "w") as f:
        f.write("\n".join(parts) + "\n")
