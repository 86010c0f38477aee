"""Fig. 10 of McCann et al. 2006: 16_16 (walk) with gravity pointing to the walker's left.

Same duration, force-matching objective. The new timing favours one leg: the stance phases of one foot
are played differently from the other's. Printed: the mean playback speed while only the left / only
the right foot is on the ground.

    python3 examples/physics_sideways_gravity.py [OUT_DIR]
"""
import numpy as np

from physics_common import load, parse_args, retime, stance_speeds

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_16")
walk = m.root_positions[-1] - m.root_positions[0]
forward = np.array([walk[0], 0.0, walk[2]]) / np.hypot(walk[0], walk[2])
left = np.cross([0.0, 1.0, 0.0], forward)  # y up: up x forward points to the walker's left
g = 9.81 * left
for tag, gravity in (("down", (0.0, -9.81, 0.0)), ("left", tuple(g))):
    r = retime(m, terms, args.out, f"physics_16_16_gravity_{tag}", duration=m.duration, gravity=gravity)
    print(f"  gravity {tag}: stance speeds {stance_speeds(r, terms)}")
