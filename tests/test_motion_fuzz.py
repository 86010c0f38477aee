"""Fuzz: randomly mutated and truncated BVH, ASF and AMC files either load into a sound motion or raise
retime's own FormatError/RetimeError, never anything else (seeded, so failures reproduce)."""
import numpy as np
import pytest

from _foundation_ref import mutate
from retime.data import bundled_path
from retime.errors import RetimeError
from retime.motion import forward_kinematics, load_motion, save_bvh

CASES = 90  # per kind; four kinds


def cut_bvh(name, frames):
    lines = bundled_path(name).read_text().splitlines()
    k = lines.index("MOTION")
    return "\n".join(lines[: k + 1] + [f"Frames: {frames}", lines[k + 2]] + lines[k + 3:k + 3 + frames]) + "\n"


def cut_amc(name, frames):
    lines = bundled_path(name).read_text().splitlines()
    return "\n".join(lines[: lines.index(str(frames + 1))]) + "\n"


@pytest.fixture(scope="module")
def sources():
    return {"mb.bvh": cut_bvh("16_15.bvh", 5), "cgspeed.bvh": cut_bvh("131_01.bvh", 5),
            "asf": bundled_path("16.asf").read_text(), "amc": cut_amc("16_15.amc", 5)}


def load_and_check(path, tmp_path):
    """Load; if that works the motion must be sound and survive a BVH round trip."""
    try:
        m = load_motion(path)
    except RetimeError as e:
        msg = str(e)
        assert "\n" not in msg and len(msg) < 400  # one line
        return False
    pos, _ = forward_kinematics(m)
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(m.translations))
    np.testing.assert_allclose(np.linalg.norm(m.rotations, axis=-1), 1.0, atol=1e-9)
    assert m.n_frames >= 1 and m.fps > 0
    save_bvh(m, tmp_path / "out.bvh")
    back = load_motion(tmp_path / "out.bvh")
    assert back.n_frames == m.n_frames
    return True


@pytest.mark.parametrize("kind", ["mb.bvh", "cgspeed.bvh", "asf", "amc"])
def test_mutated_files_fail_cleanly(kind, sources, tmp_path):
    rng = np.random.default_rng(["mb.bvh", "cgspeed.bvh", "asf", "amc"].index(kind))
    loaded = 0
    for case in range(CASES):
        if kind.endswith(".bvh"):
            path = tmp_path / kind
            path.write_bytes(mutate(sources[kind], rng).encode("utf-8", "surrogatepass"))
        else:
            asf = mutate(sources["asf"], rng) if kind == "asf" else sources["asf"]
            amc = mutate(sources["amc"], rng) if kind == "amc" else sources["amc"]
            (tmp_path / "16.asf").write_bytes(asf.encode("utf-8", "surrogatepass"))
            path = tmp_path / "16_15.amc"
            path.write_bytes(amc.encode("utf-8", "surrogatepass"))
        try:
            loaded += load_and_check(path, tmp_path)
        except RetimeError:
            raise
        except Exception as e:  # name the case so it can be replayed
            raise AssertionError(f"{kind} case {case}: {type(e).__name__}: {e}") from e
    assert 0 < loaded < CASES  # the mutations are neither all harmless nor all fatal


@pytest.mark.parametrize("name", ["16_15.bvh", "131_01.bvh", "16.asf", "16_15.amc"])
def test_every_truncation_point_fails_cleanly(name, sources, tmp_path):
    """Cut the file at 60 places spread over its length (and inside the first lines)."""
    if name.endswith(".bvh"):
        text = sources["mb.bvh" if name.startswith("16") else "cgspeed.bvh"]
    else:
        text = sources["asf" if name.endswith(".asf") else "amc"]
    cuts = sorted(set(np.linspace(0, len(text) - 1, 50).astype(int)) | set(range(0, 200, 20)))
    for cut in cuts:
        if name.endswith(".bvh"):
            path = tmp_path / name
            path.write_text(text[:cut])
        else:
            (tmp_path / "16.asf").write_text(text[:cut] if name.endswith(".asf") else sources["asf"])
            path = tmp_path / "16_15.amc"
            path.write_text(text[:cut] if name.endswith(".amc") else sources["amc"])
        try:
            load_and_check(path, tmp_path)
        except RetimeError:
            raise
        except Exception as e:
            raise AssertionError(f"{name} cut at {cut}: {type(e).__name__}: {e}") from e


def test_random_bytes_fail_cleanly(tmp_path):
    rng = np.random.default_rng(7)
    for case in range(40):
        data = bytes(rng.integers(0, 256, size=int(rng.integers(0, 400)), dtype=np.uint8))
        if case % 2:
            data = b"HIERARCHY\nROOT a\n{\n" + data
        path = tmp_path / "noise.bvh"
        path.write_bytes(data)
        with pytest.raises(RetimeError):
            load_motion(path)
