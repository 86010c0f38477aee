"""The shared foot-contact detector (retime.motion.feet): the lean path every method uses finds the
same contact states as physics' own detection along its dynamics path, and guided reaches it
without importing the physics package."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from retime.data import bundled_path
from retime.errors import RetimeError
from retime.motion import load_motion
from retime.motion.feet import foot_contacts
from retime.physics.model.dynamics import dynamics_terms

BUNDLED = ["16_03.amc", "16_06.amc", "16_15.amc", "16_15.bvh", "16_16.amc", "16_33.amc", "131_01.bvh"]
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
DEV = sorted(p for d in ("cmu", "bvh-dev") for p in (DATA / d).glob("*") if p.suffix in (".amc", ".bvh"))


def _same_as_physics(path):
    motion = load_motion(path)
    try:
        physics = dynamics_terms(motion, reference=False).contact  # detected on the full dynamics path
    except RetimeError:
        with pytest.raises(RetimeError):  # what physics refuses (one frame), the lean path refuses too
            foot_contacts(motion)
        return
    lean = foot_contacts(motion)
    assert lean.shape == physics.shape == (motion.n_frames, 4)
    assert np.array_equal(lean, physics), f"{(lean != physics).sum()} contact states differ"


@pytest.mark.parametrize("clip", BUNDLED)
def test_the_lean_detector_finds_physics_contacts_on_every_bundled_clip(clip):
    _same_as_physics(bundled_path(clip))


@pytest.mark.parametrize("path", DEV, ids=[f"{p.parent.name}/{p.name}" for p in DEV])
def test_the_lean_detector_finds_physics_contacts_on_the_dev_clips(path):
    _same_as_physics(path)


def test_the_dev_clips_are_there_or_skipped():
    if not DATA.is_dir():
        pytest.skip("../shared/data is absent")
    assert len(DEV) >= 35  # the dev data's CMU and bvh-dev clips (a wrong glob would test nothing)


def test_a_jump_has_one_flight_and_a_walk_none(jump, walk):
    """An independent check of what the states mean: 16_06 leaves the ground once, for its 0.4-0.6 s
    broad jump; a walk always has a foot down."""
    from retime.phases import flights

    found = [(a, b) for a, b in flights(foot_contacts(jump), jump.fps) if b - a > 0.2]
    assert len(found) == 1 and 0.3 < found[0][1] - found[0][0] < 0.7
    assert foot_contacts(walk).any(axis=1).all()


def test_a_rig_without_legs_is_refused_with_a_sentence():
    from retime.motion.model import Motion, Skeleton

    sk = Skeleton(names=["root", "arm"], parents=np.array([-1, 0]), offsets=np.array([[0, 0, 0], [0, 1.0, 0]]),
                  channels=[["Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"],
                            ["Xrotation", "Yrotation", "Zrotation"]])
    motion = Motion(sk, np.tile([0, 0, 0, 1.0], (10, 2, 1)), np.zeros((10, 2, 3)), 30.0)
    with pytest.raises(RetimeError, match="two-legged"):
        foot_contacts(motion)


def test_guided_does_not_import_the_physics_package():
    """Methods do not depend on each other: a guided solve, pace pull and all, leaves retime.physics
    unimported (checked in a fresh interpreter)."""
    code = ("import sys; import retime.guided; from retime.guided.api import guided_solve; "
            "from retime.motion import load_motion; from retime.data import bundled_path; "
            "r = guided_solve(load_motion(bundled_path('16_06.amc')), scale=0.6); "
            "assert r.stats is not None; "
            "print(sorted(m for m in sys.modules if m.startswith('retime.physics')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def _hysteresis_loop(height, speed, h_on, h_off, v_on, v_off):
    """The detector's state machine written out frame by frame (the vectorized one's twin)."""
    out = np.zeros(height.shape, dtype=bool)
    for p in range(height.shape[1]):
        on = False
        for i in range(len(height)):
            on = not (height[i, p] > h_off or speed[i, p] > v_off) if on else (height[i, p] < h_on and speed[i, p] < v_on)
            out[i, p] = on
    return out


def test_the_vectorized_hysteresis_equals_the_state_machine():
    from retime.motion.feet import hysteresis

    rng = np.random.default_rng(7)
    height = np.cumsum(rng.normal(0, 0.01, (2000, 4)), axis=0) % 0.08  # wanders through both thresholds
    speed = np.abs(rng.normal(1.2, 0.8, (2000, 4)))
    height[::97] = np.nan  # a gap in the capture: neither enters nor leaves
    expected = _hysteresis_loop(height, speed, 0.03, 0.05, 1.0, 2.0)
    with np.errstate(invalid="ignore"):
        got = hysteresis((height < 0.03) & (speed < 1.0), (height > 0.05) | (speed > 2.0))
    assert np.array_equal(got, expected)
    assert 0.2 < expected.mean() < 0.8  # both states are visited often
