"""Fig. 9 of McCann et al. 2006: 16_03 (high jump) under lower and higher gravity, free duration.

A ballistic flight under gravity g' retimed from a capture under g must play at sqrt(g'/g) of its speed
(its height is fixed): 0.5 for a quarter of the gravity, 1.41 for twice the gravity. Printed: flight
speed beside that value.

    python3 examples/physics_gravity.py [OUT_DIR]
"""
import math

from physics_common import load, parse_args, retime
from retime.physics.report import flight_speeds

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_03")
for factor, tag in ((0.25, "low"), (0.5, "half"), (2.0, "high")):
    r = retime(m, terms, args.out, f"physics_16_03_gravity_{tag}", gravity=(0.0, -9.81 * factor, 0.0))
    print(f"  gravity x{factor:g}: flight speed {flight_speeds(r.report)} (ballistic: {math.sqrt(factor):.2f})")
