"""``retime check --report``'s per-frame forces and centre of mass, checked from the report alone:

* Newton for the whole body: m (a_com - g) = the feet's contact forces + the residual force, on every
  frame, with a_com differentiated from the reported centre of mass (fails when a force is missing,
  scaled, in other axes or the centre of mass in other units);
* each foot's force acts at that foot (near its own ankle and toes: fails when the feet are swapped)
  and is zero when the foot carries no contact;
* the same jump written Z up in centimetres reports the same forces turned with it and the centre of
  mass in its axes and unit."""
from __future__ import annotations

import json

import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.motion import forward_kinematics, load_motion, save_bvh
from retime.motion import variants as V

G = 9.81
Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # variants.turn_up("+z"): y -> z
FEET = {"left": ("lfoot", "ltoes"), "right": ("rfoot", "rtoes")}


def _report(path, out, *args):
    code = main(["check", str(path), "--report", str(out), *args])
    assert code in (0, 1)
    return json.loads(out.read_text(), parse_constant=pytest.fail)


def _arrays(report):
    frames = report["frames"]
    force = np.array([[f["foot_force"][foot] for foot in FEET] for f in frames])  # (F, 2, 3)
    point = np.array([[f["foot_point"][foot] for foot in FEET] for f in frames])
    residual = np.array([f["residual_force"] for f in frames])
    com = np.array([f["com"] for f in frames])
    return force, point, residual, com


@pytest.fixture(scope="module")
def jumps(tmp_path_factory):
    """The jump as a Y-up BVH in metres and as a Z-up BVH in centimetres, with their reports."""
    tmp = tmp_path_factory.mktemp("forces")
    motion = load_motion(bundled_path("16_06.amc"))
    save_bvh(motion, tmp / "y.bvh")
    save_bvh(V.rescale(V.turn_up(motion, "+z"), 100.0), tmp / "z.bvh")
    return {"y": (tmp / "y.bvh", _report(tmp / "y.bvh", tmp / "y.json", "--units", "m")),
            "z": (tmp / "z.bvh", _report(tmp / "z.bvh", tmp / "z.json", "--units", "cm", "--up", "z"))}


@pytest.mark.parametrize("which, up, metres", [("y", np.array([0, 1.0, 0]), 1.0), ("z", np.array([0, 0, 1.0]), 0.01)])
def test_forces_balance_the_centre_of_mass(jumps, which, up, metres):
    path, report = jumps[which]
    force, _, residual, com = _arrays(report)
    fps = load_motion(path).fps
    accel = np.gradient(np.gradient(com * metres, 1 / fps, axis=0), 1 / fps, axis=0)
    newton = (accel + G * up) / G  # body weights
    error = np.linalg.norm(newton - force.sum(axis=1) - residual, axis=1)[2:-2]  # one-sided ends
    assert error.max() < 0.03, f"Newton off by {error.max():.3f} body weights at frame {error.argmax() + 2}"
    stance = np.array([not f["flight"] for f in report["frames"]])
    assert stance.sum() > 100 and (~stance).sum() > 20
    # the feet carry the weight in stance, nothing in flight, and the residual is small beside it
    assert np.median(force[stance].sum(axis=1) @ up) == pytest.approx(1.0, abs=0.1)
    assert np.abs(force[~stance]).max() == 0.0
    assert np.median(np.linalg.norm(residual, axis=1)) < 0.05


def test_each_foot_pushes_where_it_is(jumps):
    path, report = jumps["y"]
    force, point, _, _ = _arrays(report)
    motion = load_motion(path)
    positions, _ = forward_kinematics(motion)
    names = list(motion.skeleton.names)
    for k, (foot, joints) in enumerate(FEET.items()):
        loaded = force[:, k, 1] > 0.05
        assert loaded.sum() > 50, foot
        near = np.min([np.linalg.norm(point[:, k] - positions[:, names.index(j)] * motion.skeleton.meters_per_unit,
                                      axis=1) for j in joints], axis=0)
        assert near[loaded].max() < 0.15, f"the {foot} foot's force acts {near[loaded].max():.2f} m from it"


def test_the_axes_and_units_are_the_files(jumps):
    fy, py, ry, cy = _arrays(jumps["y"][1])
    fz, pz, rz, cz = _arrays(jumps["z"][1])
    assert len(fy) == len(fz)
    np.testing.assert_allclose(fz, fy @ Z_UP.T, atol=2e-3)
    np.testing.assert_allclose(rz, ry @ Z_UP.T, atol=2e-3)
    np.testing.assert_allclose(cz * 0.01, cy @ Z_UP.T, atol=1e-4)  # centimetres
    loaded = fy[..., 1] > 0.05
    np.testing.assert_allclose((pz * 0.01)[loaded], (py @ Z_UP.T)[loaded], atol=1e-3)
    residual_y = [f["residual"] for f in jumps["y"][1]["frames"]]
    residual_z = [f["residual"] for f in jumps["z"][1]["frames"]]
    np.testing.assert_allclose(residual_z, residual_y, atol=2e-3)
