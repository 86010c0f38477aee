"""Skeletons and motions: the data model, file formats (BVH, ASF/AMC) and forward kinematics."""
from pathlib import Path

from ..errors import FormatError
from .asf import read_amc, read_asf
from .bvh import read_bvh, write_bvh
from .fk import end_site_positions, forward_kinematics
from .model import Motion, Skeleton
from .quat import slerp

READABLE = (".bvh", ".amc")


def load_motion(path, fps=None, asf=None) -> Motion:
    """Load a BVH or AMC file. AMC files find ``X.asf`` beside ``X_NN.amc`` unless ``asf`` is given;
    they carry no frame rate, so ``fps`` defaults to CMU's 120 Hz."""
    path = Path(path)
    if fps is not None and not (fps > 0):
        raise FormatError(path, f"frame rate must be positive, got {fps}")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return read_bvh(path, fps=fps)
    if suffix == ".amc":
        return read_amc(path, asf=asf, fps=fps)
    if suffix == ".asf":
        raise FormatError(path, "is a skeleton without motion; load the .amc file (it finds this .asf)")
    raise FormatError(path, f"unknown motion format {suffix or '(no extension)'!r}; retime reads .bvh and .amc")


def save_bvh(motion: Motion, path) -> None:
    """Write ``motion`` as BVH, atomically."""
    if Path(path).suffix.lower() != ".bvh":
        raise FormatError(path, "output must be a .bvh file")
    write_bvh(motion, path)


__all__ = ["Motion", "Skeleton", "load_motion", "save_bvh", "forward_kinematics", "end_site_positions",
           "read_bvh", "write_bvh", "read_amc", "read_asf", "slerp"]
