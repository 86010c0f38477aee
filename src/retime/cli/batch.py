"""``retime batch``: retime many clips with one method on Dask distributed (see retime.batch)."""
from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import RetimeError
from ..method import METHODS  # every registered method, and check
from .common import keytime, positive_float, positive_int
from .physics import _gravity_scale

EPILOG = """examples:
  retime batch captures/ -o out/ --method linear --scale 0.5
  retime batch jobs.csv -o out/ --method guided          (header: motion,duration,scale,keytimes,reference,blend,pace)
  retime batch a.bvh b.amc -o out/ --method physics --gravity-scale 0.5 --scheduler tcp://10.0.0.5:8786

Writes OUTDIR/X.bvh, X.csv (warp) and X.json (physics report) per clip, or with --method check X.json
(check report) and X.png (its plot), mirroring each input folder, with OUTDIR/summary.csv and
OUTDIR/index.html. A re-run skips clips whose inputs and options are unchanged (OUTDIR/.retime-batch.json);
--force recomputes them. Inputs are never written over; one batch at a time writes a folder."""


def register(sub):
    p = sub.add_parser(
        "batch", help="retime many clips (files, folders, a jobs file) on Dask distributed",
        description="Run one single-clip command (linear, guided, physics or check) over many clips in parallel, on an "
                    "embedded local Dask cluster or a running scheduler. A clip that fails is recorded and the "
                    "batch goes on.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="motion files (.bvh, .amc; .fbx, .glb, .gltf with bpy), folders (walked for them), or jobs files (.csv, .toml)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="folder for the outputs (created if needed)")
    p.add_argument("--method", required=True, choices=(*METHODS, "check"),
                   help="the retiming method, or check: each clip's physical plausibility as captured, ranked")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--duration", type=positive_float, metavar="SEC", help="every clip's output duration in seconds")
    g.add_argument("--scale", type=positive_float, metavar="X", help="outputs last X times as long as their inputs")
    p.add_argument("--keytime", action="append", default=[], type=keytime, metavar="SRC=DST",
                   help="a keytime for every clip; repeat for several (a jobs file gives them per clip)")
    p.add_argument("--reference", metavar="REF", help="guided: motion whose timing to imitate (default: each clip)")
    p.add_argument("--gravity-scale", type=_gravity_scale, metavar="G", help="physics: gravity times G")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler (default: a local cluster; its workers must see the same paths)")
    p.add_argument("--workers", type=positive_int, metavar="N", help="local cluster workers (default: one per CPU)")
    p.add_argument("--force", action="store_true", help="recompute clips that a previous run finished")
    p.add_argument("--quiet", action="store_true", help="no dashboard link, progress bar or summary line")
    p.set_defaults(func=run)


def run(args):
    from ..batch.jobs import Defaults, find_clips
    from ..batch.run import run_batch

    if args.reference and args.method != "guided":
        raise RetimeError("--reference is for --method guided")
    if args.gravity_scale is not None and args.method != "physics":
        raise RetimeError("--gravity-scale is for --method physics")
    if args.method == "check" and (args.duration is not None or args.scale is not None or args.keytime):
        raise RetimeError("check judges each clip's own timing: drop --duration, --scale and --keytime")
    if args.scheduler and args.workers:
        raise RetimeError("--workers sizes the local cluster; a --scheduler has its own workers")
    outdir = Path(args.output)
    if outdir.exists() and not outdir.is_dir():
        raise RetimeError(f"{outdir}: exists and is not a folder")
    defaults = Defaults(duration=args.duration, scale=args.scale, keytimes=tuple(args.keytime),
                        reference=Path(args.reference) if args.reference else None)
    skipped: list[tuple[str, str]] = []
    clips = find_clips(args.inputs, defaults, outdir=outdir, skipped=skipped)
    for clip in clips:
        if clip.reference is not None and args.method != "guided":
            raise RetimeError(f"{clip.origin}: a reference is for --method guided")
        for name in clip.guided_options():
            if args.method != "guided":
                raise RetimeError(f"{clip.origin}: a {name} is for --method guided")
        if args.method == "linear" and clip.duration is None and clip.scale is None and not clip.keytimes:
            raise RetimeError(f"{clip.origin}: say how to retime {clip.motion}: --duration SEC, --scale X, "
                              "--keytime SRC=DST or a jobs file's columns")
    return run_batch(clips, outdir, args.method, gravity_scale=args.gravity_scale, scheduler=args.scheduler,
                     workers=args.workers, force=args.force, quiet=args.quiet, skipped=tuple(skipped))
