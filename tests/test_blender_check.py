"""The add-on's Check in the real bpy module, against ``retime check --report`` run here on the BVH the
add-on exported: the residual curve is the report's residual, the markers sit at its worst frames, the
arrows play its contact forces (and the centre of mass its centre of mass) in Blender's axes, the
character's action keeps every key, a second run replaces what the first made and Clear removes it."""
import json

import numpy as np
import pytest

from _blender_support import play_addon_script, require_bpy, run_retime

FEET = ("left", "right")


def blender_axes(v):
    """BVH (Y up) -> Blender's world (Z up), as Blender's BVH importer maps them: (x, y, z) -> (x, -z, y)."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 0], -v[..., 2], v[..., 1]], axis=-1)


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    require_bpy()
    tmp = tmp_path_factory.mktemp("check")
    # 16_06 played too fast (Frame Time x0.8, 150 fps): the check judges its landing (a flight that falls
    # at g is left out of the verdict, so the clip as captured has no worst frame to mark)
    done, result = play_addon_script(tmp, "check_driver.py", frame_time_factor=0.8)
    result["printed"] = done.stdout + done.stderr  # Blender prints an operator's reports when it has no window
    code, _, err = run_retime("check", tmp / "first" / "source.bvh", "--report", tmp / "cli.json")
    assert code in (0, 1), err
    return result, json.loads((tmp / "cli.json").read_text())


def test_the_residual_curve_is_the_reports(checked):
    result, report = checked
    assert result["status"] == ["FINISHED"]
    expected = [f["residual"] for f in report["frames"]]
    assert len(result["residual_curve"]) == len(expected) == result["end"] - result["start"] + 1
    np.testing.assert_allclose(result["residual_curve"], expected, atol=1e-3)
    assert max(expected) > 1.0  # 16_06 lands hard: the curve is not flat
    frame, value = result["residual_played"]  # the property plays with the scene
    assert value == pytest.approx(expected[frame - result["start"]], abs=1e-3)


def test_markers_sit_at_the_worst_frames(checked):
    result, report = checked
    start = result["start"]
    markers = result["first"]["markers"]
    worst = sorted(frame for name, frame in markers if name.startswith("check: worst"))
    assert worst == sorted(start + i for i in report["summary"]["worst_frames"]) and worst
    over = [frame for name, frame in markers if name.startswith("check: over")]
    residual = np.array([f["residual"] for f in report["frames"]])
    for frame in over:  # each starts a run over the threshold
        i = frame - start
        assert residual[i] > report["residual_threshold"] and (i == 0 or residual[i - 1] <= report["residual_threshold"])
    thr = report["residual_threshold"]
    starts = {start + i for i in range(len(residual)) if residual[i] > thr and (i == 0 or residual[i - 1] <= thr)}
    assert starts and starts <= {frame for _, frame in markers}  # every run over the threshold is marked
    assert ["96", 150] in markers  # the user's own markers stay


def test_the_arrows_play_the_contact_forces(checked):
    result, report = checked
    length = result["force_length"]
    assert length > 0
    played = result["played"]
    for foot in FEET:
        arrow = played[f"Retime Force {foot}"]
        force = blender_axes([f["foot_force"][foot] for f in report["frames"]])
        np.testing.assert_allclose(np.array(arrow["z"]) / length, force, atol=2e-3)
        loaded = np.linalg.norm(force, axis=1) > 0.05
        point = blender_axes([f["foot_point"][foot] for f in report["frames"]])
        np.testing.assert_allclose(np.array(arrow["location"])[loaded], point[loaded], atol=1e-3)
        assert loaded.sum() > 50 and (~loaded).sum() > 20  # stance and flight both seen
    residual = blender_axes([f["residual_force"] for f in report["frames"]])
    np.testing.assert_allclose(np.array(played["Retime Residual Force"]["z"]) / length, residual, atol=2e-3)
    com = blender_axes([f["com"] for f in report["frames"]])
    np.testing.assert_allclose(played["Retime Centre of Mass"]["location"], com, atol=1e-3)
    ground = np.array(played["Retime CoM Ground"]["location"])
    np.testing.assert_allclose(ground[:, :2], com[:, :2], atol=1e-3)
    assert np.ptp(ground[:, 2]) == 0 and ground[0, 2] < com[:, 2].min()  # one floor, under the body


def test_the_character_is_untouched_and_a_rerun_replaces(checked):
    result, _ = checked
    assert result["action_untouched"]
    first, again = result["first"], result["again"]
    assert result["status_again"] == ["FINISHED"]
    assert again == first  # the same objects, actions, collection and markers by name: replaced, not added
    assert result["force_length_again"] == 2.0
    assert set(result["in_collection"]) == set(first["objects"]) and len(first["objects"]) == 6
    assert result["cleared"] == {"objects": [], "collections": [], "actions": [], "markers": [["96", 150]]}


def test_the_verdict_is_reported(checked):
    result, report = checked
    assert report["verdict"].startswith("NOT physical as captured") and "[frame_rate]" in report["verdict"]
    assert f"Check '16_06': {report['verdict']}" in result["printed"], result["printed"][-2000:]


def test_no_armature_is_one_line(checked):
    message = checked[0]["no_armature"]
    assert "no active object: select the armature to check" in message and "\n" not in message
    assert {"force_length", "exchange_folder"} <= set(checked[0]["registered"])
