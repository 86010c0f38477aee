"""``retime demo``: linear, guided and physics retiming of a bundled CMU jump to the same shorter
duration, written as an HTML report with plots, a side-by-side video and the numbers.

Everything the report shows is computed here from the clip: nothing is canned. Each method runs
through the contract of :mod:`retime.method`; one that refuses the clip (a ``RetimeError``, e.g.
physics on a four-legged rig) is listed in the report with its reason instead of results.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from retime.errors import RetimeError
from retime.method import METHODS  # the method registry
from retime.phases import interval_speed, longest_flight

DEFAULT_CLIP = "16_06.amc"


@dataclass
class MethodResult:
    name: str
    curve: Any = None
    motion: Any = None
    seconds: float | None = None
    report: dict | None = None  # physics report (normalised), if any
    feasible_fraction: float | None = None
    flight_speed: float | None = None
    error: str | None = None
    settings: str = ""
    files: dict = field(default_factory=dict)
    raw_report: dict | None = None  # the method's own report, as written to disk
    physics: Any = None  # the physics method's full result (regions, objective)


@dataclass
class DemoResult:
    out_dir: Path
    clip: str
    source_duration: float
    duration: float
    fps: float
    n_frames: int
    flight: tuple[float, float] | None
    methods: list[MethodResult]
    files: dict
    total_seconds: float
    render_fps: float | None = None
    frame_range: tuple[int, int] | None = None
    clip_path: Path | None = None  # the file read (the commands in the report name it)

    @property
    def bundled(self) -> bool:
        """Whether the clip is one of retime's bundled CMU clips."""
        from retime.data import CMU_DIR

        return self.clip_path is not None and self.clip_path.resolve().parent == CMU_DIR

    @property
    def report_path(self) -> Path:
        return self.out_dir / "report.html"


# ---------------------------------------------------------------------- clip and flight phase
def find_clip(name: str = DEFAULT_CLIP) -> Path:
    """A bundled clip by name (``retime.data``), else the repository's data/cmu, else a path."""
    p = Path(name)
    if p.suffix and p.exists():
        return p
    try:
        from retime.data import bundled_path

        return Path(bundled_path(p.name))
    except (ImportError, FileNotFoundError):
        pass
    here = Path(__file__).resolve()
    for base in (here.parents[1] / "data" / "cmu", here.parents[3] / "data" / "cmu"):
        if (base / p.name).exists():
            return base / p.name
    raise RetimeError(f"{name}: clip not found (neither bundled with retime nor an existing file)")


def flight_phase(motion) -> tuple[float, float] | None:
    """(start, end) source times of the longest stretch with no foot on the ground of the motion as
    physics sees it (conformed), or None (also when physics cannot conform it: the methods say why)."""
    from retime.motion.feet import foot_contacts

    try:
        return longest_flight(foot_contacts(motion), np.arange(motion.n_frames) / motion.fps)
    except RetimeError:
        return None


def flight_speed(curve, flight: tuple[float, float] | None) -> float | None:
    """Mean playback speed over the flight: source flight time / output time spent in it."""
    return None if flight is None or curve is None else interval_speed(curve, *flight)


# ---------------------------------------------------------------------- the methods
SETTINGS = {
    "linear": "uniform speed-up: p(t) = t * S / T",
    "guided": "reference = the input itself (preserve its natural timing), default skip limit and k",
    "physics": "objective: match the original's torques and stay feasible (Eq. 14)",
}


NOTICE = ("guided", "physics")  # the methods with numba kernels, whose Settings have ``progress``


def run_method(name: str, motion, duration: float) -> MethodResult:
    """One method through the contract of :mod:`retime.method`, to ``duration`` (progress on stderr)."""
    from retime.method import Request, settings_type, solve

    # defaults, with the compile notice where a method compiles kernels (a first run is slow)
    settings = settings_type(name)(**({"progress": True} if name in NOTICE else {}))
    result = solve(name, motion, Request(duration=duration, settings=settings))
    timings = result.report.summary["timings"]
    out = MethodResult(name, curve=result.curve, seconds=timings.get("method"), settings=SETTINGS.get(name, ""))
    if name == "physics":
        from retime.viz.regions import normalise_report

        out.raw_report = result.report.to_json()
        out.report = normalise_report(out.raw_report)
        out.feasible_fraction = float(result.report.summary["feasible_fraction"])
        out.physics = result.detail
    return out


# ---------------------------------------------------------------------- the demo
def run_demo(
    out_dir: str | os.PathLike = "retime-demo",
    clip: str = DEFAULT_CLIP,
    scale: float = 0.5,
    methods=tuple(METHODS),  # every registered method
    fps: float = 30.0,
    panel_size: tuple[int, int] = (480, 400),
    video: bool = True,
    quiet: bool = False,
    frames: tuple[int, int] | None = None,
) -> DemoResult:
    """Run the demo and write ``out_dir/report.html`` with its files beside it.

    ``frames``: (first, last) source frames to keep (inclusive), to run on part of the clip."""
    from retime.io_util import check_not_input
    from retime.motion import load_motion, save_bvh
    from retime.viz.plot import plot_timing
    from retime.viz.progress import progress
    from retime.warp import apply_timing, output_duration

    t_start = time.perf_counter()
    if not (0 < scale < 10):
        raise RetimeError(f"--scale must be between 0 and 10, got {scale}")
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise RetimeError(f"unknown method {unknown[0]!r}; choose from {', '.join(METHODS)}")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise RetimeError(f"{out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    clip_path = find_clip(clip)
    stem = clip_path.stem

    steps = 2 + len(methods) + (1 if video else 0) + 1
    with progress(steps, "retime demo", quiet, unit="step") as bar:
        bar.set_postfix_str(f"loading {clip_path.name}")
        motion = load_motion(clip_path)
        if frames is not None:
            a, b = int(frames[0]), int(frames[1])
            if not (0 <= a < b < motion.n_frames):
                raise RetimeError(f"--frames {a}:{b}: the clip has frames 0 to {motion.n_frames - 1}; "
                                  "give FIRST:LAST with FIRST < LAST")
            motion = motion.frames(slice(a, b + 1))
        duration = output_duration(motion.duration, motion.fps, scale=scale)  # as --scale gives it
        flight = flight_phase(motion)
        bar.update(1)

        results: list[MethodResult] = []
        for name in methods:
            bar.set_postfix_str(name)
            try:
                r = run_method(name, motion, duration)
            except RetimeError as exc:  # a method that refuses this clip: the report says why, the others go on
                r = MethodResult(name, error=str(exc))
            if r.curve is not None:
                r.motion = apply_timing(motion, r.curve)
                r.flight_speed = flight_speed(r.curve, flight)
                warp = out / f"{stem}_{name}.csv"
                bvh = out / f"{stem}_{name}.bvh"
                check_not_input(warp, clip_path)
                check_not_input(bvh, clip_path)
                r.curve.to_csv(warp, motion.fps)
                save_bvh(r.motion, bvh)
                r.files = {"warp": warp.name, "bvh": bvh.name}
                if r.report is not None:
                    from retime.physics.report import write_report as write_physics_report

                    rep = out / f"{stem}_{name}_report.json"
                    # with the regions per source frame, so that `retime plot --regions` can draw any frame
                    write_physics_report(r.raw_report, rep, regions=r.physics.regions)
                    r.files["report"] = rep.name
            results.append(r)
            bar.update(1)

        done = [r for r in results if r.curve is not None]
        phys_result = next((r.physics for r in done if r.physics is not None), None)
        for r in done:
            if r.feasible_fraction is None and phys_result is not None:
                from retime.physics.regions.feasibility import curve_feasibility

                r.feasible_fraction = curve_feasibility(r.curve, phys_result.dynamics, phys_result.regions,
                                                        motion.fps).fraction
        files: dict[str, str] = {}
        bar.set_postfix_str("plots")
        if done:
            plot_timing([(r.name, r.curve) for r in done], out / "timing.png",
                        title=f"{stem}: {motion.duration:.2f} s retimed to {duration:.2f} s", size=(10.5, 4.0))
            files["timing"] = "timing.png"
            plot_timing([(r.name, r.curve) for r in done], out / "timing.svg", size=(10.5, 4.0))
            files["timing_svg"] = "timing.svg"
        phys = next((r for r in done if r.report is not None), None)
        if phys is not None:
            from retime.viz.regions import plot_contact_strip, plot_regions

            frame = _region_frame(phys.report, motion.fps)
            if phys.physics is not None and frame is not None:
                from retime.viz.regions import physics_frame_region

                physics_frame_region(phys.physics, phys.report, frame)
            if frame is not None and phys.report["frames"][frame]["region"] is not None:
                plot_regions(phys.report, frame, out / "region.png",
                             title=f"{stem}, physics retiming: output frame {frame}")
                files["region"] = "region.png"
                files["region_frame"] = str(frame)
                src = phys.report["frames"][frame]["source_frame"]
                files["region_source_frame"] = "" if src is None else str(src)
            else:  # no region to show: the contact and feasibility strip alone
                plot_contact_strip(phys.report, out / "contacts.png", size=(10.5, 2.2))
                files["contacts"] = "contacts.png"
        bar.update(1)

        render_fps = None
        if video:
            bar.set_postfix_str("video")
            from retime.viz.render import Renderer, track_from_motion
            from retime.viz.video import VideoWriter

            # feet in contact (from the physics report) highlighted in every panel
            src_contacts = None
            if phys is not None:
                from retime.viz.regions import report_source_contacts

                try:
                    src_contacts = report_source_contacts(phys.report, motion.skeleton, motion.n_frames)
                except RetimeError:
                    src_contacts = None
            tracks = [track_from_motion(motion, "original", contacts=src_contacts)]
            for r in done:
                contacts = None
                if src_contacts is not None:
                    from retime.viz.regions import contacts_through_curve

                    contacts = contacts_through_curve(src_contacts, motion.fps, r.curve, r.motion.n_frames, r.motion.fps)
                tracks.append(track_from_motion(r.motion, r.name, curve=r.curve, contacts=contacts))
            renderer = Renderer(tracks, fps=fps, panel_size=panel_size, columns=2 if len(tracks) == 4 else None)
            # poster: the moment the uniformly sped-up clip is in mid-flight
            t_poster = (0.5 * (flight[0] + flight[1]) if flight else 0.5 * motion.duration) * duration / motion.duration
            mid = min(max(int(round(t_poster * fps)), 0), renderer.n_frames - 1)
            with open(out / ".poster.tmp.png", "wb") as f:
                renderer.frame_image(mid).save(f, format="PNG")
            os.replace(out / ".poster.tmp.png", out / "compare.png")
            t0 = time.perf_counter()
            with VideoWriter(out / "compare.mp4", renderer.width, renderer.height, fps) as writer:
                with progress(renderer.n_frames, "render", quiet, unit="frame") as fbar:
                    for k in range(renderer.n_frames):
                        writer.write(renderer.frame(k))
                        fbar.update(1)
            render_fps = renderer.n_frames / (time.perf_counter() - t0)
            files["video"] = "compare.mp4"
            files["poster"] = "compare.png"
            files["video_size"] = f"{renderer.width}x{renderer.height}"
            files["video_frames"] = str(renderer.n_frames)
            bar.update(1)

        result = DemoResult(
            out_dir=out, clip=clip_path.name, clip_path=clip_path, frame_range=frames, source_duration=motion.duration, duration=duration, fps=motion.fps,
            n_frames=motion.n_frames, flight=flight, methods=results, files=files,
            total_seconds=0.0, render_fps=render_fps,
        )
        bar.set_postfix_str("report")
        from retime.report.html import write_report

        result.total_seconds = time.perf_counter() - t_start
        write_report(result, scale=scale, video_fps=fps)
        bar.update(1)
    return result


def _region_frame(report: dict, fps: float) -> int | None:
    """The output frame showing source frame 143 (McCann et al.'s Fig. 6 frame of 16_06) if the
    clip has it, else the output frame in the middle of the clip."""
    frames = report["frames"]
    if not frames:
        return None
    src = [f["source_frame"] for f in frames]
    if all(s is not None for s in src) and min(src) <= 143 <= max(src):
        return int(np.argmin([abs(s - 143) for s in src]))
    return len(frames) // 2
