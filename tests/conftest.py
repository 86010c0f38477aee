"""Fixtures shared by the test modules: the bundled CMU clips, loaded once per module (a module
may change what it is given without reaching the others)."""
import sys
from pathlib import Path

import pytest

# the benchmarks' own fixtures (the Fig. 12 chains) are tested too
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from retime.data import bundled_path
from retime.motion import load_motion


@pytest.fixture(scope="module")
def jump():
    """CMU 16_06: a standing broad jump, 3.38 s at 120 Hz."""
    return load_motion(bundled_path("16_06.amc"))


@pytest.fixture(scope="module")
def high_jump():
    """CMU 16_03: a jump with a longer flight."""
    return load_motion(bundled_path("16_03.amc"))


@pytest.fixture(scope="module")
def walk():
    """CMU 16_15: a walk."""
    return load_motion(bundled_path("16_15.amc"))
