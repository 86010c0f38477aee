"""Fig. 1 of McCann et al. 2006: 16_06 (forward jump) in half the time.

The idle time before the jump and after the landing absorbs the speed-up; the ballistic flight, which
cannot be retimed physically, keeps (nearly) its natural speed. Compare with a uniform speed-up, whose
flight plays at 2x.

    python3 examples/physics_half_duration.py [OUT_DIR]
"""
from physics_common import load, parse_args, retime

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_06")
r = retime(m, terms, args.out, "physics_16_06_half", scale=0.5)
for p in r.report["summary"]["phases"]:
    print(f"  {p['state']:6s} source {p['source_start']:.2f}-{p['source_end']:.2f} s: speed {p['speed']:.2f}x")
