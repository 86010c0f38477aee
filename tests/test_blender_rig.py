"""A rig whose controls drive its deform bones through constraints (Rigify's layout, built small in the real
bpy module, see blender_scripts/rig_driver.py): physics and check read the evaluated deform skeleton,
while Bake retimes the animated controls, and the deform bones then play retime's own output for the
deform skeleton's BVH. Before, the add-on exported every bone and refused the rig (two root bones)."""
import json

import numpy as np
import pytest

from _blender_support import (TOLERANCE, blender_env, build_addon, joint_positions_blender, max_error_over_height,
                              play_addon_script, require_bpy, retime_wrapper, run_bpy, run_retime)

CASES = {"linear_rig": ["linear", "--scale", "0.5"], "physics_rig": ["physics", "--scale", "0.5"]}


@pytest.fixture(scope="module")
def rigged(tmp_path_factory):
    require_bpy()
    tmp = tmp_path_factory.mktemp("rig")
    return tmp, play_addon_script(tmp, "rig_driver.py")[1]


def test_the_rig_has_two_hierarchies(rigged):
    _, result = rigged
    assert result["drives_deform"] and "2 root bones" in result["all_bones"]  # what the add-on refused before


def test_check_reads_the_deform_skeleton(rigged):
    tmp, result = rigged
    assert result["check"] == ["FINISHED"]
    motion, names, expected, height = joint_positions_blender(tmp / "16_06.bvh")
    _, exported_names, exported, _ = joint_positions_blender(tmp / "rig_check" / "source.bvh")
    assert not any(n.startswith("CTRL-") for n in exported_names)
    error = max_error_over_height(list(names), expected, list(exported_names), exported, height)
    assert error < TOLERANCE, f"the exported deform skeleton is {error:.2e} of the height off the motion"


@pytest.mark.parametrize("name", list(CASES))
def test_bake_retimes_the_controls_and_the_deform_bones_follow(rigged, name):
    tmp, result = rigged
    case = result[name]
    assert case["status"] == ["FINISHED"], case
    assert case["animated"] and all(b.startswith("CTRL-") for b in case["animated"])  # the controls were retimed
    folder = tmp / name
    code, _, err = run_retime(*CASES[name][:1], folder / "source.bvh", *CASES[name][1:], "-o", folder / "cli.bvh")
    assert code == 0, err
    motion, names, expected, height = joint_positions_blender(folder / "cli.bvh")
    got = np.load(tmp / f"{name}.npz")
    assert len(got["frames"]) == motion.n_frames
    error = max_error_over_height(list(names), expected, list(got["names"]), got["heads"], height)
    assert error < TOLERANCE, f"{name}: deform bones {error:.2e} of the height off retime's output"


@pytest.fixture(scope="module")
def rigify(tmp_path_factory):
    """A Rigify rig generated from the human meta-rig, its controls keyed (blender_scripts/rigify_driver.py)."""
    require_bpy()
    tmp = tmp_path_factory.mktemp("rigify")
    exe = retime_wrapper(tmp)
    done = run_bpy("rigify_driver.py", build_addon(tmp / "dist"), tmp, tmp / "results.json",
                   env=blender_env(tmp, RETIME_EXECUTABLE=str(exe)))
    return tmp, json.loads((tmp / "results.json").read_text()), done


def test_a_generated_rigify_rig_is_read_and_retimed(rigify):
    """Rigify parents its DEF bones to non-deform ORG bones (the thighs, the shoulders and the face have no
    deform ancestor): the add-on refused it ("98 root deform bones"). Its deform skeleton, hung together by
    geometry, exports as the DEF bones play; Bake retimes the controls, and the DEF bones then play retime's
    own output for that skeleton's BVH."""
    tmp, result, _ = rigify
    assert result["drives_deform"] and result["deform_bones"] == 160
    source = np.load(tmp / "source.npz")
    _, names, exported, height = joint_positions_blender(tmp / "rigify_linear" / "source.bvh")
    assert len(names) == result["deform_bones"]  # every DEF bone, in one hierarchy
    error = max_error_over_height(list(names), exported, list(source["names"]), source["heads"], height)
    assert error < TOLERANCE, f"the exported deform skeleton is {error:.2e} of the height off the DEF bones"
    # at 0.5 every output frame is a source frame; at 0.7 most fall between, where Rigify's IK chains blend
    # otherwise than retime's interpolation of the deform skeleton: the bound of 1e-3 of the height
    for name, scale, n_out, tolerance in [("rigify_linear", "0.5", 21, TOLERANCE), ("rigify_between", "0.7", 29, 1e-3)]:
        case = result[name]
        assert case["status"] == ["FINISHED"], case
        assert case["animated"] and not any(b.startswith("DEF-") for b in case["animated"])  # the controls
        folder = tmp / name
        code, _, err = run_retime("linear", folder / "source.bvh", "--scale", scale, "-o", folder / "cli.bvh")
        assert code == 0, err
        motion, names, expected, height = joint_positions_blender(folder / "cli.bvh")
        got = np.load(tmp / f"{name}.npz")
        assert len(got["frames"]) == motion.n_frames == n_out
        error = max_error_over_height(list(names), expected, list(got["names"]), got["heads"], height)
        assert error < tolerance, f"{name}: DEF bones {error:.2e} of the height off retime's output"


def test_check_runs_on_a_generated_rigify_rig(rigify):
    _, result, done = rigify
    assert result["check"] == ["FINISHED"], result["check"]
    assert "Check 'rigAction': " in done.stdout + done.stderr
