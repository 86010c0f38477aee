"""A clip that is not physical as captured is said to be so, with the likely cause; a real one is not."""
import numpy as np
import pytest

from retime.data import bundled_path
from retime.motion import load_motion, save_bvh
from retime.physics.api import physics_warp
from retime.physics.model.contacts import detect_contacts
from retime.physics.model.body import default_body
from retime.motion.conform import conform


@pytest.fixture(scope="module")
def jump():
    return load_motion(bundled_path("16_06.amc"))


def _summary(motion, **kw):
    return physics_warp(motion, scale=0.7, **kw).report["summary"]


def test_a_real_capture_is_physical(jump):
    s = _summary(jump)
    assert s["source_check"]["physical"] and s["warnings"] == []


def test_wrong_up_axis_is_said(jump, tmp_path):
    path = tmp_path / "j.bvh"
    save_bvh(jump, path)
    m = load_motion(path, up="z", units="m")
    s = _summary(m)
    assert not s["source_check"]["physical"] and s["source_check"]["off_share"] > 0.8
    assert any("up axis is wrong" in c and "--up" in c for c in s["source_check"]["causes"])
    assert "not physical as captured" in s["warnings"][0]


def test_treadmill_is_said(walk):
    tr = walk.translations.copy()
    tr[:, 0, [0, 2]] = tr[0, 0, [0, 2]]  # the travel taken out: the feet are carried back while planted
    s = _summary(walk.replace(translations=tr))
    assert not s["source_check"]["physical"]
    assert any("feet move while at floor height" in c and "static floor" in c for c in s["source_check"]["causes"])
    assert s["source_check"]["codes"] == ["treadmill"] and "a treadmill" in s["warnings"][0]  # physics warns
    assert _summary(walk)["source_check"]["physical"]


def test_root_locked_export_is_said(jump):
    tr = jump.translations.copy()
    tr[:, 0] = tr[0, 0]  # the root pinned: the body hangs where it started
    s = _summary(jump.replace(translations=tr))
    assert not s["source_check"]["physical"]
    assert any("root never moves" in c for c in s["source_check"]["causes"])


def test_contacts_follow_a_drifting_floor(walk):
    base = conform(walk).motion
    body = default_body(base.skeleton, motion=base)
    c0 = detect_contacts(base, body)
    tr = base.translations.copy()
    tr[:, 0, 1] += np.linspace(0.0, 0.25, walk.n_frames)  # the capture floor drifts up by 25 cm
    drift = base.replace(translations=tr)
    c1 = detect_contacts(drift, default_body(drift.skeleton, motion=drift))
    # with one floor for the whole clip this walk kept 32% of its stance frames and 59% of the states
    assert c0.any(axis=1).mean() > 0.9 and c1.any(axis=1).mean() > 0.9
    assert np.mean(c0 == c1) > 0.9


def test_cli_prints_the_warning(jump, tmp_path, capsys):
    from retime.cli import main

    path = tmp_path / "j.bvh"
    save_bvh(jump, path)
    assert main(["physics", str(path), "-o", str(tmp_path / "o.bvh"), "--scale", "0.7", "--up", "x", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "warning: this clip is not physical as captured" in out and "--up" in out


def _strict_json(text):
    import json

    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_report_is_valid_json_with_a_one_frame_last_phase(jump, tmp_path):
    from retime.physics.report import write_report

    m = jump.frames(slice(0, 120))
    contact = np.ones((m.n_frames, 4), dtype=bool)
    contact[-1] = False  # the last frame alone is a flight: a phase with no span
    r = physics_warp(m, scale=0.7, contacts=contact)
    path = tmp_path / "r.json"
    write_report(r.report, path)
    data = _strict_json(path.read_text())
    assert all(np.isfinite(p["speed"]) for p in data["summary"]["phases"])
    r.report["summary"]["least_duration"] = float("inf")  # any non-finite number becomes null
    write_report(r.report, path)
    assert _strict_json(path.read_text())["summary"]["least_duration"] is None
