"""The motion data model: a skeleton (hierarchy, rest offsets, channels) and a motion (per-frame
local joint rotations and translations at a frame rate)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")

# Length units a file may use, and the body height (metres) used to guess which one a BVH uses.
LENGTH_UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048,
                "cmu": 0.0254 / 0.45}  # CMU's ASF unit, which many CMU BVH conversions keep
TYPICAL_HEIGHT_M = 1.7


def channel_dof(channel: str) -> str:
    """'Xrotation' -> 'rx', 'Yposition' -> 'ty' (ASF dof names)."""
    return ("t" if channel.endswith("position") else "r") + channel[0].lower()


@dataclass
class Skeleton:
    """A joint hierarchy. Joint 0 is the root; every parent comes before its children.

    offsets are rest offsets from the parent joint in file units; the rest pose has every local
    rotation equal to the identity, in a y-up world.
    """

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[list[str]]
    end_sites: list[tuple[int, np.ndarray]] = field(default_factory=list)
    meters_per_unit: float = 1.0
    dof: list[list[str]] | None = None  # ASF dof names per joint, e.g. ['rx', 'rz']
    limits: list[list[tuple[float, float]]] | None = None  # ASF limits (degrees/units) per dof
    source: str = ""
    up: str = "+y"  # the world axis the file calls up ('+y', '-z', ...), detected when loaded
    angles: str = "deg"  # the unit a file's rotation channels were written in ('deg' or 'rad')
    notes: list[str] = field(default_factory=list)  # what the reader noticed and the user should know
    frame: object = None  # the FrameGuess of retime.motion.frame that set up and meters_per_unit

    def __post_init__(self):
        self.parents = np.asarray(self.parents, dtype=np.int64)
        self.offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        if self.dof is None:
            self.dof = [[channel_dof(c) for c in ch] for ch in self.channels]

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}; joints: {', '.join(self.names)}") from None

    def children(self, j: int) -> list[int]:
        return [int(c) for c in np.nonzero(self.parents == j)[0]]

    @property
    def n_dofs(self) -> int:
        return sum(len(d) for d in self.dof)

    def same_structure(self, other: "Skeleton") -> list[str]:
        """Names of joints that differ (missing on either side or with another parent); [] if equal."""
        mine = {n: (self.names[p] if p >= 0 else None) for n, p in zip(self.names, self.parents)}
        theirs = {n: (other.names[p] if p >= 0 else None) for n, p in zip(other.names, other.parents)}
        return sorted(n for n in set(mine) | set(theirs) if mine.get(n, "?") != theirs.get(n, "?"))


@dataclass
class Motion:
    """Per-frame local joint rotations (unit quaternions, x y z w) and translations at ``fps``."""

    skeleton: Skeleton
    rotations: np.ndarray  # (F, J, 4)
    translations: np.ndarray  # (F, J, 3); root: world position, others: usually the rest offset
    fps: float

    def __post_init__(self):
        self.rotations = np.asarray(self.rotations, dtype=float)
        self.translations = np.asarray(self.translations, dtype=float)
        self.fps = float(self.fps)

    @property
    def n_frames(self) -> int:
        return self.rotations.shape[0]

    @property
    def duration(self) -> float:
        return (self.n_frames - 1) / self.fps

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_frames) / self.fps

    @property
    def root_positions(self) -> np.ndarray:
        return self.translations[:, 0]

    def replace(self, **changes) -> "Motion":
        return dataclasses.replace(self, **changes)

    def frames(self, index) -> "Motion":
        """A motion made of the selected frames (slice or index array)."""
        return self.replace(rotations=self.rotations[index], translations=self.translations[index])


def guess_meters_per_unit(height_units: float) -> float:
    """The common length unit that makes a body of this height closest to a typical human."""
    if not np.isfinite(height_units) or height_units <= 0:
        return 1.0
    scores = {u: abs(np.log(height_units * s / TYPICAL_HEIGHT_M)) for u, s in LENGTH_UNITS.items()}
    return LENGTH_UNITS[min(scores, key=scores.get)]
