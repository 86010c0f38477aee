"""A long capture for the scaling benchmarks: CMU subject 13's long takes (13_29, 13_17) played
one after another until it lasts the asked number of minutes, each joined to the one before by a
half-second crossfade (slerped rotations, blended translations) with its root moved to continue
where the previous take ended. Built in memory; nothing is written unless asked."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

SHARED = ROOT.parent / "shared" / "data" / "cmu"
TAKES = ("13_29", "13_17")
CROSSFADE_S = 0.5


def long_capture(minutes: float, shared: Path = SHARED):
    """A Motion of ``minutes`` minutes at 120 Hz made of subject 13's long takes (see above)."""
    from retime.motion import load_motion
    from retime.motion.quat import slerp

    takes = [load_motion(shared / f"{t}.amc") for t in TAKES]
    fps = takes[0].fps
    want = int(round(minutes * 60 * fps)) + 1
    fade = int(round(CROSSFADE_S * fps))
    up = 1  # ASF is y-up: the root's horizontal plane is x, z
    rot = [takes[0].rotations]
    tra = [takes[0].translations]
    n = takes[0].n_frames
    k = 1
    while n < want:
        nxt = takes[k % len(takes)]
        k += 1
        r, t = nxt.rotations.copy(), nxt.translations.copy()
        shift = tra[-1][-fade, 0] - t[0, 0]  # the new take's first frame at the start of the fade
        shift[up] = 0.0
        t[:, 0] += shift
        w = (np.arange(1, fade + 1) / (fade + 1))[:, None, None]
        r[:fade] = slerp(rot[-1][-fade:], r[:fade], w[..., 0])
        t[:fade] = (1 - w) * tra[-1][-fade:] + w * t[:fade]
        rot[-1] = rot[-1][:-fade]
        tra[-1] = tra[-1][:-fade]
        rot.append(r)
        tra.append(t)
        n += nxt.n_frames - fade
    rotations = np.concatenate(rot)[:want]
    translations = np.concatenate(tra)[:want]
    return takes[0].replace(rotations=rotations, translations=translations)


if __name__ == "__main__":
    import argparse

    from retime.motion import save_bvh

    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("minutes", type=float)
    p.add_argument("-o", "--output", required=True, help="BVH to write (e.g. under /tmp: it is large)")
    a = p.parse_args()
    m = long_capture(a.minutes)
    save_bvh(m, a.output)
    print(f"wrote {a.output}: {m.n_frames} frames, {m.duration:.1f} s")
