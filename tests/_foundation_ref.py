"""Independent reference code for the foundation tests: a plain BVH reader and a per-joint matrix
forward kinematics built on SciPy rotation matrices (no retime code, no quaternions), plus helpers to
write synthetic BVH files and to mutate files for fuzzing."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

SHARED_CMU = Path(os.environ.get("RETIME_SHARED_CMU", "/work/shared/data/cmu"))


def shared_clip(name):
    """Path of a clip in the developers' shared data set, or None if this machine lacks it."""
    path = SHARED_CMU / name
    return path if path.exists() else None


# -- an independent BVH reader ---------------------------------------------------------------------
def ref_read_bvh(text):
    """names, parents, offsets (J,3), channels per joint, end sites [(j, offset)], frame values (F, C),
    frame time. Braces may share lines with names; joint names may hold spaces."""
    text = text.replace("{", "\n{\n").replace("}", "\n}\n")
    lines = [ln.strip() for ln in text.replace("\r\n", "\n").replace("\r", "\n").split("\n")]
    lines = [ln for ln in lines if ln]
    names, parents, offsets, channels, ends = [], [], [], [], []
    stack, in_end, k = [], False, 0
    while True:
        ln = lines[k]
        k += 1
        word = ln.split()[0].upper()
        if word in ("ROOT", "JOINT"):
            names.append(ln.split(None, 1)[1].strip())
            parents.append(stack[-1] if stack else -1)
            offsets.append(np.zeros(3))
            channels.append([])
        elif word == "END":
            in_end = True
            ends.append([stack[-1], np.zeros(3)])
        elif word == "{":
            if not in_end:
                stack.append(len(names) - 1)
        elif word == "}":
            if in_end:
                in_end = False
            else:
                stack.pop()
        elif word == "OFFSET":
            vals = np.array([float(v) for v in ln.split()[1:4]])
            if in_end:
                ends[-1][1] = vals
            else:
                offsets[stack[-1]] = vals
        elif word == "CHANNELS":
            channels[stack[-1]] = ln.split()[2:]
        elif word == "MOTION":
            break
    n_frames = int(lines[k].split(":")[1])
    frame_time = float(lines[k + 1].split(":")[1])
    rows = [[float(v) for v in ln.split()] for ln in lines[k + 2:k + 2 + n_frames]]
    return names, np.array(parents), np.array(offsets), channels, ends, np.array(rows), frame_time


def ref_fk(parents, offsets, channels, values):
    """Global joint positions (F, J, 3) and rotation matrices (F, J, 3, 3), joint by joint with 3x3
    matrices: a joint's position channels replace its offset; its rotation channels multiply, in the
    listed order, on the right (rotations about the joint's moving axes)."""
    n_frames = values.shape[0]
    n = len(parents)
    pos = np.zeros((n_frames, n, 3))
    rot = np.zeros((n_frames, n, 3, 3))
    col = 0
    for j in range(n):
        local_t = np.tile(np.asarray(offsets[j], float), (n_frames, 1))
        local_r = np.tile(np.eye(3), (n_frames, 1, 1))
        for c in channels[j]:
            axis = c[0].lower()
            if c.lower().endswith("position"):
                local_t[:, "xyz".index(axis)] = values[:, col]
            else:
                m = Rotation.from_euler(axis, values[:, col, None], degrees=True).as_matrix()
                local_r = local_r @ m
            col += 1
        p = parents[j]
        if p < 0:
            pos[:, j] = local_t
            rot[:, j] = local_r
        else:
            pos[:, j] = pos[:, p] + np.einsum("fab,fb->fa", rot[:, p], local_t)
            rot[:, j] = rot[:, p] @ local_r
    return pos, rot


def ref_bvh_positions(path):
    """Joint names and global positions (F, J, 3) of a BVH file, by the reference reader and FK."""
    text = Path(path).read_bytes().decode("latin-1")
    names, parents, offsets, channels, _, values, _ = ref_read_bvh(text)
    pos, _ = ref_fk(parents, offsets, channels, values)
    return names, pos


# -- synthetic BVH files ----------------------------------------------------------------------------
def bvh_text(names, parents, offsets, channels, values, frame_time=1 / 30, end_sites=(), newline="\n",
             indent="\t", brace_on_joint_line=False, end_site_word="End Site", frames_declared=None):
    """A BVH file in one of the many styles exporters use. Joints must be numbered depth first."""
    children = {j: [k for k, p in enumerate(parents) if p == j] for j in range(len(names))}
    out = ["HIERARCHY"]

    def fmt(v):
        return " ".join(f"{x:.6f}" for x in v)

    def joint(j, d):
        ind = indent * d
        head = f"{ind}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}"
        if brace_on_joint_line:
            out.append(head + " {")
        else:
            out.extend([head, ind + "{"])
        out.append(f"{ind}{indent}OFFSET {fmt(offsets[j])}")
        if channels[j]:
            out.append(f"{ind}{indent}CHANNELS {len(channels[j])} {' '.join(channels[j])}")
        for c in children[j]:
            joint(c, d + 1)
        for k, off in end_sites:
            if k == j:
                if brace_on_joint_line:
                    out.append(f"{ind}{indent}{end_site_word} {{")
                else:
                    out.extend([f"{ind}{indent}{end_site_word}", f"{ind}{indent}{{"])
                out.extend([f"{ind}{indent * 2}OFFSET {fmt(off)}", f"{ind}{indent}}}"])
        out.append(ind + "}")

    joint(0, 0)
    n = len(values) if frames_declared is None else frames_declared
    out += ["MOTION", f"Frames: {n}", f"Frame Time: {frame_time:.8f}"]
    out += [" ".join(f"{v:.6f}" for v in row) for row in values]
    return newline.join(out) + newline


# -- mutations for fuzzing --------------------------------------------------------------------------
GARBAGE = ["nan", "NaN", "inf", "-inf", "abc", "", "{", "}", "1e999", "-", ".", "1.2.3", "0x10", "\t",
           "ROOT", "JOINT", "End", "MOTION", "Frames:", "CHANNELS", "OFFSET", "root", ":", "#", "begin",
           "end", "dof", "\x00", "é", "-0", "999999999999", "3", "0"]


def mutate(text: str, rng: np.random.Generator) -> str:
    """One to three random edits: truncate, drop/duplicate/swap lines, replace a token, insert noise."""
    for _ in range(int(rng.integers(1, 4))):
        lines = text.split("\n")
        op = int(rng.integers(0, 8))
        if op == 0 and len(text) > 1:
            text = text[: int(rng.integers(0, len(text)))]
            continue
        i = int(rng.integers(0, len(lines)))
        if op == 1:
            del lines[i]
        elif op == 2:
            lines.insert(i, lines[i])
        elif op == 3:
            k = int(rng.integers(0, len(lines)))
            lines[i], lines[k] = lines[k], lines[i]
        elif op in (4, 5):
            tokens = lines[i].split(" ")
            tokens[int(rng.integers(0, len(tokens)))] = GARBAGE[int(rng.integers(0, len(GARBAGE)))]
            lines[i] = " ".join(tokens)
        elif op == 6:
            pos = int(rng.integers(0, len(lines[i]) + 1))
            noise = "".join(chr(int(c)) for c in rng.integers(32, 127, size=int(rng.integers(1, 4))))
            lines[i] = lines[i][:pos] + noise + lines[i][pos:]
        else:
            if lines[i]:
                pos = int(rng.integers(0, len(lines[i])))
                lines[i] = lines[i][:pos] + lines[i][pos + 1:]
        text = "\n".join(lines)
    return text
