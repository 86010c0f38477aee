"""``retime physics``: physics-based retiming (McCann, Pollard, Srinivasa 2006)."""
from __future__ import annotations

import argparse
import math

from ..physics.constants import MAX_GRAVITY, G
from ..physics.method import MASS_FACTORS, OBJECTIVES, OPTIMIZER_NAMES, STARTS, Settings
from .common import add_duration_args, add_motion_args, add_output_args, check_output, load_input, positive_float, \
    said_written, say_warnings

EPILOG = """examples:
  retime physics 16_06.amc -o half.bvh --scale 0.5 --report half.json
      half the duration; the flight keeps its natural speed
  retime physics 16_03.amc -o moon.bvh --gravity-scale 0.25 --warp moon.csv
      a quarter of the gravity, free duration: the flight plays at about half speed
  retime physics 16_16.amc -o side.bvh --gravity -9.81,0,0 --duration 4.25
  retime physics 16_16.amc -o heavy.bvh --mass lfemur=10 --write-body body.toml
  retime physics 16_06.amc -o early.bvh --keytime 2.3=1.9 --duration 3.383

Without --duration or --scale the duration is free: the optimizer chooses it."""


def _vector3(text):
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 3:
        raise argparse.ArgumentTypeError(f"gravity must be X,Y,Z in m/s^2 (e.g. 0,-9.81,0), got {text!r}")
    if not all(math.isfinite(x) for x in v) or math.hypot(*v) > MAX_GRAVITY:
        raise argparse.ArgumentTypeError(f"gravity must be finite and at most {MAX_GRAVITY:g} m/s^2 long, got {text!r}")
    return tuple(v)




def _gravity_scale(text):
    g = positive_float(text)
    if g * G > MAX_GRAVITY:
        raise argparse.ArgumentTypeError(f"at most {MAX_GRAVITY / G:.0f} (a hundred g), got {text}")
    return g


def _mass(text):
    name, sep, value = text.partition("=")
    try:
        f = float(value)
    except ValueError:
        f = -1.0
    if not sep or not name or not (MASS_FACTORS[0] <= f <= MASS_FACTORS[1]):
        raise argparse.ArgumentTypeError(f"mass factor must look like SEGMENT=FACTOR with FACTOR from {MASS_FACTORS[0]:g} "
                                         f"to {MASS_FACTORS[1]:g} (e.g. lfemur=10), got {text!r}")
    return name, f


def register(sub):
    p = sub.add_parser(
        "physics", help="physics-based retiming: keep the motion physically plausible (McCann et al. 2006)",
        description="Retime a motion so that its new timing stays physically plausible for a body (feasible contact "
                    "forces and joint torques), optionally under changed gravity or segment masses, matching the "
                    "original's torques (match) or using the least effort (minimize).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_motion_args(p)
    add_output_args(p)
    add_duration_args(p)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--gravity", type=_vector3, metavar="X,Y,Z", help="gravity vector in m/s^2 in the file's axes (default 9.81 down its up axis, "
                   "detected or given by --up)")
    g.add_argument("--gravity-scale", type=_gravity_scale, metavar="G", help="gravity times G (0.25: a quarter of the gravity)")
    p.add_argument("--mass", type=_mass, action="append", default=[], metavar="SEGMENT=FACTOR",
                   help="multiply a segment's mass (skeleton joint name, e.g. lfemur=10); repeat for several")
    d = Settings()  # every default below is Settings', passed on only when given
    p.add_argument("--objective", choices=OBJECTIVES,
                   help=f"match the original's joint torques or minimize them (default {d.objective})")
    p.add_argument("--body", metavar="BODY.toml", help="body model (masses, inertias, soles, torque limits); default: "
                   "anthropometric segments of 70 kg, limits from the motion")
    p.add_argument("--write-body", metavar="BODY.toml", help="write the body model used (with the torque limits estimated "
                   "from the motion) for editing")
    p.add_argument("--contacts", metavar="CONTACTS.csv", help="foot contact states per frame (default: detected)")
    p.add_argument("--friction", type=positive_float, metavar="MU", help="friction coefficient (default: the body's, 0.5)")
    p.add_argument("--torque-scale", type=positive_float, metavar="X",
                   help=f"scale all torque limits (default {d.torque_scale:g})")
    p.add_argument("--method", dest="optimizer", choices=OPTIMIZER_NAMES,
                   help="optimizer: L-BFGS polished by Newton's method on the banded problem (newton), "
                        "L-BFGS alone (lbfgs), the paper's gradient descent (gd), or SLSQP "
                        f"(default {d.optimizer})")
    p.add_argument("--start", choices=STARTS,
                   help="where the optimizer starts: the grid-optimal timing found by dynamic programming "
                        "(global; not with keytimes) or the uniform timing, as in the paper "
                        f"(uniform; default {d.start})")
    p.add_argument("--report", metavar="REPORT.json", help="per output frame: contact, feasibility, distance, "
                   "torque norm; each source frame's feasible region (for retime plot --regions)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def run(args):
    from ..method import Request, solve
    from ..outputs import write_retiming
    from ..physics.report import flight_speeds

    check_output(args)
    m = load_input(args)
    masses = {}
    for name, f in args.mass:
        masses[name] = masses.get(name, 1.0) * f
    given = {k: getattr(args, k) for k in ("objective", "torque_scale", "optimizer", "start")
             if getattr(args, k) is not None}
    settings = Settings(gravity=args.gravity, gravity_scale=args.gravity_scale, mass_factors=masses,
                        body=args.body, contacts=args.contacts, friction=args.friction, progress=not args.quiet,
                        **given)
    answer = solve("physics", m, Request(args.duration, args.scale, args.keytime, settings))
    result = answer.detail
    duration = None if args.duration is None and args.scale is None else answer.curve.duration  # None: free
    retimed = write_retiming("physics", m, answer, args.output, args.warp, args.report, source=args.motion)
    said_written(args, m, retimed)
    if args.write_body:
        from ..physics.model.body import write_body

        terms = result.terms
        write_body(terms.body, args.write_body, torque_limits=terms.joint_torque_limits(),
                   note=f"torque limits estimated from {args.motion}")
    s = result.report["summary"]
    for note in s.get("conform_notes", []):
        print(f"note: {note}")
    say_warnings(s)
    if not args.quiet:
        least = s.get("least_duration")
        if duration is not None and least is not None and duration < least - 0.5 / m.fps:
            print(f"note: no timing of this clip is physical in less than {least:.3f} s (the fastest timing through "
                  f"its feasible regions); {duration:.3f} s leaves some frames outside them (see the report)")
        fl = ", ".join(f"{x:.2f}" for x in flight_speeds(result.report)) or "none"
        print(f"physics: {s['feasible_fraction'] * 100:.1f}% of output frames feasible; flight speed {fl}; "
              f"mean speed {s['mean_speed']:.2f}" + (f"; report {args.report}" if args.report else "")
              + (f"; body {args.write_body}" if args.write_body else ""))
    return 0
