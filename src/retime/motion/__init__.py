"""Skeletons and motions: the data model, file formats (BVH, ASF/AMC, FBX/glTF through Blender) and
forward kinematics."""
from .asf import read_amc, read_asf
from .bvh import read_bvh, write_bvh
from .files import READABLE, WRITABLE, load_motion, save_bvh, save_motion
from .fk import end_site_positions, forward_kinematics
from .model import Motion, Skeleton
from .quat import slerp

__all__ = ["Motion", "Skeleton", "load_motion", "save_bvh", "save_motion", "READABLE", "WRITABLE", "forward_kinematics", "end_site_positions",
           "read_bvh", "write_bvh", "read_amc", "read_asf", "slerp"]
