"""Fig. 8 of McCann et al. 2006: a point in the middle of 16_06's flight constrained to play earlier.

The duration stays the same; the optimizer finds slack time before the jump and leaves the highly
dynamic part (takeoff, flight, landing) at its natural speed.

    python3 examples/physics_keytime.py [OUT_DIR]
"""
import numpy as np

from physics_common import load, parse_args, retime

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_06")
flight = np.flatnonzero(~np.asarray(terms.contact, dtype=bool).any(axis=1))
s_mid = float(terms.times[flight[len(flight) // 2]])
r = retime(m, terms, args.out, "physics_16_06_keytime", duration=m.duration, keytimes=[(s_mid, s_mid - 0.4)])
print(f"  mid-flight source {s_mid:.3f} s plays at {float(r.spline.inverse(s_mid)):.3f} s (asked {s_mid - 0.4:.3f} s)")
