"""The README's examples as a new user runs them: from any folder, not from the data folder."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from retime.cli.main import build_parser

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"


def test_the_python_example_runs_from_any_folder(tmp_path):
    """It read load_motion("16_06.amc"), which fails unless run from the folder holding the clip."""
    section = REPO.joinpath("README.md").read_text().split("\n## Python\n", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                          env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"}, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "out.bvh").is_file()


def test_help_examples_that_name_a_bundled_clip_say_where_it_is(tmp_path):
    parser = build_parser()
    (commands,) = [a.choices for a in parser._actions if a.choices and "linear" in a.choices]
    noted = 0
    for name, command in commands.items():
        epilog = command.epilog or ""
        if name == "demo" or not re.search(r"\b16_\d\d\.amc\b", epilog):
            continue
        noted += 1
        assert "bundled with retime" in epilog, name
        snippet = re.search(r'python3 -c "(.*?)" prints', " ".join(epilog.split())).group(1)
        done = subprocess.run([sys.executable, "-c", snippet], cwd=tmp_path, capture_output=True, text=True,
                              env={"PYTHONPATH": str(SRC)})
        assert Path(done.stdout.strip()).is_file(), (name, done.stderr)
    assert noted >= 6  # info, convert, linear, guided, physics, render, check, edit
