"""Fig. 11 of McCann et al. 2006: 16_16 (walk) with the left femur ten times heavier.

Same duration, force-matching objective. The character lingers where the heavy thigh is over the
supporting foot. Printed: mean playback speed while only the left / only the right foot is down,
beside the unchanged body.

    python3 examples/physics_heavy_femur.py [OUT_DIR]
"""
from physics_common import load, parse_args, retime, stance_speeds

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_16")
for tag, masses in (("normal", None), ("heavy_lfemur", {"lfemur": 10.0})):
    r = retime(m, terms, args.out, f"physics_16_16_{tag}", duration=m.duration, mass_factors=masses)
    print(f"  {tag}: stance speeds {stance_speeds(r, terms)}")
