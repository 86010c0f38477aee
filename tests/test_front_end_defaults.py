"""Each method's Settings is the only carrier of its defaults: the command line passes on only what is
given (and names Settings' values in its help), the editor's controls start at Settings' values, the
keyword wrappers and the Blender add-on agree with them."""
import argparse
from dataclasses import fields, replace

import numpy as np
import pytest
from _blender_support import addon_module

from retime.cli import main
from retime.cli.main import build_parser
from retime.data import bundled_path
from retime.errors import RetimeError
from retime.guided.limits import BACK_POINTER, MAX_SKIP_LIMIT
from retime.guided.method import Settings as GuidedSettings
from retime.physics.constants import G, STANDARD_GRAVITY
from retime.physics.method import Settings as PhysicsSettings

# command-line option -> Settings field, for every option that carries one of a Settings' values
GUIDED_OPTIONS = {"max_skip": "max_skip", "neighbors": "neighbors", "analysis_fps": "analysis_fps",
                  "smoothing": "smoothing", "score": "score", "steadiness": "steadiness", "pace": "pace", "blend": "blend",
                  "weights": "weights", "upsample": "upsample", "fast": "fast"}
PHYSICS_OPTIONS = {"objective": "objective", "torque_scale": "torque_scale", "optimizer": "optimizer",
                   "start": "start", "friction": "friction", "gravity": "gravity", "gravity_scale": "gravity_scale"}


def subcommand(name):
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest: a for a in sub.choices[name]._actions}


@pytest.mark.parametrize("method, settings, table", [("guided", GuidedSettings(), GUIDED_OPTIONS),
                                                     ("physics", PhysicsSettings(), PHYSICS_OPTIONS)])
def test_the_command_line_leaves_defaults_to_settings(method, settings, table):
    options = subcommand(method)
    for dest, name in table.items():
        action = options[dest]
        if isinstance(action, argparse._StoreTrueAction):
            assert getattr(settings, name) is False
            continue
        assert action.default is None, dest  # nothing restated: the Settings' value applies
        value = getattr(settings, name)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            assert f"default {value:g}" in action.help, (dest, action.help)
        elif isinstance(value, str):
            assert f"default {value}" in action.help or f"{value} (default" in action.help, (dest, action.help)
    if method == "guided":
        assert f"at most {MAX_SKIP_LIMIT}" in options["max_skip"].help
    else:
        assert tuple(options["optimizer"].choices) and settings.optimizer in options["optimizer"].choices


@pytest.mark.parametrize("method", ["guided", "physics"])
def test_a_bare_command_asks_for_settings_defaults(tmp_path, monkeypatch, method):
    """What the command hands to solve when no option is given is Settings() itself."""
    import importlib

    seen = {}

    def capture(name, motion, request):
        seen["settings"] = request.settings
        raise RetimeError("captured")

    monkeypatch.setattr(importlib.import_module(f"retime.cli.{method}"), "solve", capture, raising=False)
    monkeypatch.setattr("retime.method.solve", capture)
    assert main([method, str(bundled_path("16_33.amc")), "-o", str(tmp_path / "o.bvh"), "--quiet"]) == 2
    want = GuidedSettings() if method == "guided" else PhysicsSettings()
    assert seen["settings"] == replace(want, progress=False)


def test_the_editors_controls_start_at_settings():
    from retime.editor.methods import Clip, GuidedMethod, PhysicsMethod
    from retime.motion import load_motion

    guided = {p.name: p.default for p in GuidedMethod.params}
    d = GuidedSettings()
    assert (guided["max_skip"], guided["neighbors"], guided["fast"], guided["blend"], guided["pace"]) == (
        d.max_skip, d.neighbors, d.fast, d.blend, d.pace)
    physics = {p.name: p.default for p in PhysicsMethod.param_specs(Clip("c", load_motion(bundled_path("16_33.amc"))))}
    p = PhysicsSettings()
    assert (physics["objective"], physics["alpha"]) == (p.objective, p.alpha)
    assert physics["gravity"] == pytest.approx(G) == pytest.approx(-STANDARD_GRAVITY[1])


def test_the_keyword_wrappers_take_settings_fields_and_nothing_else(jump):
    from retime.guided import guided_solve
    from retime.physics import physics_warp

    with pytest.raises(RetimeError, match="unknown option 'max_skips'"):
        guided_solve(jump, scale=0.5, max_skips=4)
    with pytest.raises(RetimeError, match="unknown option 'alfa'"):
        physics_warp(jump, scale=0.5, alfa=3.0)
    assert {f.name for f in fields(GuidedSettings)} >= set(GUIDED_OPTIONS.values())


def test_the_skip_limit_is_the_back_pointers_range():
    assert MAX_SKIP_LIMIT == np.iinfo(BACK_POINTER).max
    GuidedSettings(max_skip=MAX_SKIP_LIMIT)
    with pytest.raises(RetimeError, match=f"between 1 and {MAX_SKIP_LIMIT}"):
        GuidedSettings(max_skip=MAX_SKIP_LIMIT + 1)


def test_the_blender_add_on_defaults_are_retimes():
    defaults = addon_module("options").DEFAULTS
    assert (defaults["blend"], defaults["pace"]) == (GuidedSettings().blend, GuidedSettings().pace)
    assert PhysicsSettings().gravity_scale is None and defaults["gravity_scale"] == 1.0  # None: standard gravity
