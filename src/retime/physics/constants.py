"""Physical constants and defaults the physics modules share (one definition each)."""
from ..motion.feet import PATH_SMOOTHING_S


G = 9.81  # standard gravity, m/s^2
STANDARD_GRAVITY = (0.0, -G, 0.0)  # in the y-up world physics works in
MAX_GRAVITY = 1000.0  # m/s^2: a hundred g, the most any gravity may be
# seconds: the Gaussian low-pass of the path before it is differentiated (physics.api says why);
# every method's contact detection reads the same path
DEFAULT_SMOOTHING = PATH_SMOOTHING_S
