"""Can a clip tell a wrong length unit from a wrong frame rate? Per file and reading (the unit as
detected, and each ``--units`` given), the body's size (legs, hip to ankle), the flights' gravity and
the time factor it gives, and the uniform rate at which the stance frames' contact forces explain the
body's wrench best (:mod:`retime.physics.stance_rate`, here on double support too, where a jump has
no single support), with ``retime check``'s codes and cautions.

Flights and stance forces depend on the unit and the rate only through unit x rate^2 (a body s times
larger moving sqrt(s) times slower is the same to physics): reading a clip in another unit moves the
stance rate by the same factor as the flight's, and only the body's size is left to tell them apart.

    python3 benchmarks/unit_or_rate.py                       # jumping.bvh and its Frame Time x1.25, as read and in inches
    python3 benchmarks/unit_or_rate.py FILE --frame-time 1.25 --units in,cm
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from retime.motion import load_motion
from retime.motion import mistakes as M
from retime.motion.files import with_detected_frame
from retime.physics.api import prepare_regions
from retime.physics.plausibility import check_source
from retime.physics.stance_rate import _minimum, stance_rate

JUMPING = Path(__file__).resolve().parents[2] / "shared" / "data" / "bvh-dev" / "jumping.bvh"


def stance_frames(terms, pd0) -> tuple[np.ndarray, np.ndarray]:
    """(single, double) support frames (F,) bool, both away from flights by two smoothing widths."""
    from scipy.ndimage import binary_dilation

    from retime.physics.stance_rate import single_support

    spf = int(terms.samples_per_frame)
    contact = np.asarray(pd0.contact, dtype=bool)[::spf]
    single = single_support(contact, float(terms.fps), float(terms.smoothing))
    both = contact[:, :2].any(axis=1) & contact[:, 2:].any(axis=1)
    stance = contact.any(axis=1)
    near = binary_dilation(~stance, iterations=max(1, int(round(2 * terms.smoothing * terms.fps)))) \
        if (~stance).any() else np.zeros(len(stance), bool)
    return single, both & ~near


def reading(label: str, motion) -> str:
    terms, pd0, _, regions = prepare_regions(motion)
    verdict = check_source(motion, terms, regions)
    frame = motion.skeleton.frame
    single, double = stance_frames(terms, pd0)
    parts = []
    for name, frames in (("single", single), ("double", double)):
        if not frames.any():
            parts.append(f"{name}: none")
            continue
        s = stance_rate(terms, pd0, frames=frames)
        pooled = _minimum(s.residual) if s.residual.size else None
        parts.append(f"{name} {frames.sum()} frames: least residual at {pooled:.3f}" if pooled is not None
                     else f"{name} {frames.sum()} frames: no minimum")
    f = verdict.flight
    flight = "no flight" if f.ratio is None else f"flight {f.ratio:.3f} g -> time factor {f.time_factor:.3f}"
    codes = ",".join(verdict.codes + [c.code for c in verdict.cautions]) or "physical"
    return (f"{label:28s} 1 unit = {motion.skeleton.meters_per_unit:.5f} m ({frame.unit_confidence}), legs "
            f"{frame.leg_m:.2f} m, {motion.fps:.2f} fps: {flight}; stance {'; '.join(parts)}; check: {codes}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--frame-time", default="1,1.25", help="comma-separated Frame Time factors (mistakes)")
    ap.add_argument("--units", default="in", help="comma-separated units to read each in besides the detected one")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)
    files = args.files or ([JUMPING] if JUMPING.exists() else [])
    if not files:
        print("no files: give some, or put ../shared/data beside the repository")
        return 1
    for path in files:
        base = load_motion(path)
        for k in (float(x) for x in args.frame_time.split(",")):
            m = base if k == 1.0 else M.wrong_frame_time(base, k)
            print(reading(f"{path.name} x{k:g}, as read", m), flush=True)
            for unit in args.units.split(","):
                read = with_detected_frame(path.name, m.replace(skeleton=_copy(m.skeleton)), units=unit)
                print(reading(f"{path.name} x{k:g}, in {unit}", read), flush=True)
    return 0


def _copy(skeleton):
    import dataclasses

    return dataclasses.replace(skeleton, notes=list(skeleton.notes))


if __name__ == "__main__":
    sys.exit(main())
