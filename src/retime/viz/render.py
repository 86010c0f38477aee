"""Offscreen stick-figure rendering of motions, several side by side and in sync.

The renderer works on plain arrays (joint positions in metres, world y-up, and parent indices), so
it is independent of the file format.  Drawing uses Pillow's C rasteriser at twice the output size
and a 2x2 box reduction for anti-aliasing; the camera and projection of every frame are computed
with NumPy up front, so the per-frame Python work is a few dozen draw calls.  Frames are encoded
with PyAV (libx264 for .mp4/.mkv/.mov, the GIF encoder for .gif).

Each panel has a steady camera: a fixed viewing direction (a three-quarter side view of the
direction of travel, or of the facing direction for motions that stay in place), a fixed height,
and a horizontal position that follows a Gaussian-smoothed root trajectory.  The ground grid is
fixed in the world, so the floor slides past when the character travels.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Iterator, Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from retime.errors import RetimeError
from retime.viz.video import VideoWriter
from retime.warp import frame_bracket, lerp_frames

# Colours (RGB).  One accent per panel, chosen by label when it names a method.
METHOD_COLORS = {
    "original": (70, 86, 110),
    "linear": (214, 96, 77),
    "guided": (67, 147, 195),
    "physics": (77, 163, 106),
}
PALETTE = [(70, 86, 110), (214, 96, 77), (67, 147, 195), (77, 163, 106), (153, 112, 171), (224, 160, 60)]
CONTACT_COLOR = (255, 176, 0)
SKY_TOP = (236, 240, 245)
SKY_BOTTOM = (250, 251, 252)
FLOOR_NEAR = (226, 230, 236)
FLOOR_FAR = (244, 246, 249)
GRID_COLOR = (180, 188, 200)
SHADOW_COLOR = (204, 209, 217)
TEXT_COLOR = (40, 46, 56)
MUTED_TEXT = (110, 118, 130)

_SS = 2  # supersampling factor


def method_color(label: str, index: int) -> tuple[int, int, int]:
    """Accent colour for a panel: fixed for the method names, else from a palette."""
    key = label.strip().lower()
    for name, color in METHOD_COLORS.items():
        if name in key:
            return color
    return PALETTE[index % len(PALETTE)]


def _font(size: int, bold: bool = False) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """DejaVu Sans (shipped with matplotlib, a dependency) or Pillow's default font."""
    try:
        import matplotlib

        name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
        path = os.path.join(os.path.dirname(matplotlib.__file__), "mpl-data", "fonts", "ttf", name)
        return ImageFont.truetype(path, size)
    except Exception:  # pragma: no cover - fallback when matplotlib's fonts are missing
        return ImageFont.load_default(size)


@dataclass
class Track:
    """One animated skeleton to draw in a panel.

    positions: (F, J, 3) global joint positions in metres, y up, sampled at ``fps``.
    parents: (J,) parent index per joint, -1 for roots.
    names: joint names (optional; used to colour left/right limbs and find the head).
    speed: (F,) playback speed ds/dt shown per frame (None: the motion plays at 1x).
    source_time: (F,) source time shown per frame (None: same as the output time).
    contacts: (F, J) bool, joints in contact with the ground per frame (highlighted).
    """

    positions: np.ndarray
    parents: np.ndarray
    fps: float
    label: str = ""
    names: Sequence[str] | None = None
    speed: np.ndarray | None = None
    source_time: np.ndarray | None = None
    contacts: np.ndarray | None = None
    color: tuple[int, int, int] | None = None

    def __post_init__(self):
        self.positions = np.asarray(self.positions, dtype=np.float64)
        self.parents = np.asarray(self.parents, dtype=np.int64)
        if self.positions.ndim != 3 or self.positions.shape[2] != 3 or self.positions.shape[0] < 1:
            raise RetimeError(f"track {self.label!r}: positions must have shape (frames, joints, 3), got {self.positions.shape}")
        n_frames, n_joints = self.positions.shape[:2]
        if self.parents.shape != (n_joints,):
            raise RetimeError(f"track {self.label!r}: {n_joints} joints but {self.parents.shape[0]} parent indices")
        if not (self.fps > 0 and math.isfinite(self.fps)):
            raise RetimeError(f"track {self.label!r}: fps must be positive, got {self.fps}")
        if not np.all(np.isfinite(self.positions)):
            raise RetimeError(f"track {self.label!r}: joint positions contain NaN or infinity")
        for name in ("speed", "source_time"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=np.float64)
                if value.shape != (n_frames,):
                    raise RetimeError(f"track {self.label!r}: {name} must have one value per frame ({n_frames})")
                setattr(self, name, value)
        if self.contacts is not None:
            self.contacts = np.asarray(self.contacts, dtype=bool)
            if self.contacts.shape != (n_frames, n_joints):
                raise RetimeError(f"track {self.label!r}: contacts must have shape ({n_frames}, {n_joints})")

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def duration(self) -> float:
        return (self.n_frames - 1) / self.fps


def frame_count(duration: float, fps: float) -> int:
    """Number of video frames for a clip of ``duration`` seconds: both ends included."""
    return int(round(duration * fps)) + 1


def _sample(track: Track, times: np.ndarray) -> dict:
    """Linear interpolation of a track's per-frame data at ``times`` (clamped to the clip)."""
    u = np.clip(times * track.fps, 0.0, track.n_frames - 1)
    i0, i1, w = frame_bracket(u, track.n_frames)
    out = {"positions": lerp_frames(track.positions, i0, i1, w), "index": np.rint(u).astype(np.int64)}
    out["speed"] = None if track.speed is None else lerp_frames(track.speed, i0, i1, w)
    out["source_time"] = (
        np.minimum(times, track.duration)
        if track.source_time is None
        else lerp_frames(track.source_time, i0, i1, w)
    )
    out["contacts"] = None if track.contacts is None else track.contacts[out["index"]]
    return out


def _sides(names: Sequence[str] | None, parents: np.ndarray) -> np.ndarray:
    """-1 for left, +1 for right, 0 for centre joints, from the joint names."""
    sides = np.zeros(len(parents), dtype=np.int64)
    if names is None:
        return sides
    for j, name in enumerate(names):
        n = name.lower()
        if re.match(r"^(left|l(?!ower)[a-z_])", n) or n.endswith(("_l", ".l")):
            sides[j] = -1
        elif re.match(r"^(right|r(?!oot)[a-z_])", n) or n.endswith(("_r", ".r")):
            sides[j] = 1
    return sides


def _find_joint(names: Sequence[str] | None, pattern: str) -> int | None:
    if names is None:
        return None
    for j, name in enumerate(names):
        if re.search(pattern, name.lower()):
            return j
    return None


def _travel_direction(track: Track) -> np.ndarray:
    """Unit horizontal vector: the direction of travel, else the facing direction, else +x."""
    root = track.positions[:, 0, :]
    d = root[-1] - root[0]
    d[1] = 0.0
    if np.linalg.norm(d) > 0.4:
        return d / np.linalg.norm(d)
    left = _find_joint(track.names, r"^(l|left).*(hip|femur|upleg|thigh)")
    right = _find_joint(track.names, r"^(r|right).*(hip|femur|upleg|thigh)")
    if left is not None and right is not None:
        lr = track.positions[0, left] - track.positions[0, right]
        fwd = np.cross(lr, [0.0, 1.0, 0.0])
        fwd[1] = 0.0
        if np.linalg.norm(fwd) > 1e-6:
            return fwd / np.linalg.norm(fwd)
    return np.array([1.0, 0.0, 0.0])


def _gaussian_smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0 or len(x) < 2:
        return x.copy()
    from scipy.ndimage import gaussian_filter1d

    return gaussian_filter1d(x, sigma, axis=0, mode="nearest")


@dataclass
class _Camera:
    """Per-frame pinhole cameras sharing one orientation (the steady camera of a panel)."""

    centers: np.ndarray  # (N, 3)
    right: np.ndarray  # (3,)
    up: np.ndarray  # (3,)
    forward: np.ndarray  # (3,)
    focal: float
    cx: float
    cy: float
    near: float = 0.15

    def to_camera(self, points: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        rel = points - (self.centers[k] if np.ndim(k) == 0 else self.centers[k][:, None, :])
        basis = np.stack([self.right, self.up, self.forward], axis=1)
        return rel @ basis

    def project(self, cam: np.ndarray) -> np.ndarray:
        z = np.maximum(cam[..., 2], self.near)
        return np.stack([self.cx + self.focal * cam[..., 0] / z, self.cy - self.focal * cam[..., 1] / z], axis=-1)


@dataclass
class Panel:
    """Everything precomputed for one panel: camera, projected joints, static background."""

    track: Track
    color: tuple[int, int, int]
    xy: np.ndarray  # (N, J, 2) projected joints, supersampled pixels
    depth: np.ndarray  # (N, J)
    shadow_xy: np.ndarray  # (N, J, 2)
    scale: np.ndarray  # (N, J) pixels per metre at each joint
    camera: _Camera
    ground: float
    sampled: dict
    background: Image.Image
    grid: list
    side: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    head: tuple[int, int | None] | None = None


class Renderer:
    """Draws ``tracks`` side by side at ``fps``; ``frame(k)`` returns an (H, W, 3) uint8 image.

    Panels are laid out in ``columns`` columns (default: all in one row).  All panels share the
    output clock: frame k shows time k / fps in every panel; a track that is
    shorter than the longest holds its last pose (its clock stops and is shown as finished).
    """

    def __init__(
        self,
        tracks: Sequence[Track],
        fps: float = 30.0,
        panel_size: tuple[int, int] = (480, 540),
        camera_distance: float | None = None,
        follow_sigma: float | None = 0.35,
        show_timeline: bool = True,
        columns: int | None = None,
    ):
        if not tracks:
            raise RetimeError("nothing to render: no motion given")
        if not (fps > 0 and math.isfinite(fps)):
            raise RetimeError(f"render fps must be positive, got {fps}")
        w, h = int(panel_size[0]), int(panel_size[1])
        if w < 64 or h < 64:
            raise RetimeError(f"panel size {w}x{h} is too small (at least 64x64)")
        # libx264 with yuv420p needs even sizes
        self.panel_w = w + (w % 2)
        self.panel_h = h + (h % 2)
        self.fps = float(fps)
        self.tracks = list(tracks)
        self.duration = max(t.duration for t in self.tracks)
        self.n_frames = frame_count(self.duration, self.fps)
        self.times = np.minimum(np.arange(self.n_frames) / self.fps, self.duration)
        self.show_timeline = show_timeline
        self.timeline_h = 58 if show_timeline else 0
        S = _SS
        self._font_label = _font(17 * S, bold=True)
        self._font_text = _font(13 * S)
        self._font_small = _font(10 * S)
        # each panel looks across its own direction of travel; retimed versions of one motion
        # share their path, hence the same view, so they compare directly
        self.panels = [self._make_panel(t, i, camera_distance, follow_sigma) for i, t in enumerate(self.tracks)]
        n = len(self.panels)
        self.columns = n if not columns else max(1, min(int(columns), n))
        self.rows = -(-n // self.columns)
        self.width = self.panel_w * self.columns
        self.height = self.panel_h * self.rows

    # ------------------------------------------------------------------ setup
    def _make_panel(self, track: Track, index: int, camera_distance, follow_sigma) -> Panel:
        S = _SS
        W, H = self.panel_w * S, self.panel_h * S
        view_h = H - self.timeline_h * S
        sampled = _sample(track, self.times)
        pos = sampled["positions"]
        all_y = track.positions[..., 1]
        ground = float(np.min(all_y))
        stand = track.positions[0]
        body_h = float(np.clip(np.max(stand[:, 1]) - np.min(stand[:, 1]), 0.5, 3.0))
        # vertical range the camera must show: the standing body, or the highest point reached
        # (a high jump), whichever is taller
        top = float(np.percentile(track.positions[..., 1].max(axis=1), 99.5))
        extent = float(np.clip(max(body_h, top - ground), 0.5, 4.0))

        fov = math.radians(38.0)
        focal = (view_h / 2) / math.tan(fov / 2)
        dist = camera_distance if camera_distance else 1.4 * extent / (2 * math.tan(fov / 2))
        # steady camera: fixed orientation, smoothed horizontal root position
        d = _travel_direction(track)
        side = np.array([-d[2], 0.0, d[0]])
        yaw = math.radians(28.0)
        back = math.cos(yaw) * side + math.sin(yaw) * d
        back /= np.linalg.norm(back)
        root = pos[:, 0, :].copy()
        if follow_sigma is None:  # a still camera over the mean root position
            smooth = np.broadcast_to(root.mean(axis=0), root.shape)
        else:
            smooth = _gaussian_smooth(root, min(follow_sigma * self.fps, 4.0 * len(root)))
        target = np.empty_like(smooth)
        target[:, 0] = smooth[:, 0]
        target[:, 2] = smooth[:, 2]
        target[:, 1] = ground + 0.5 * extent
        elevation = 0.4 * body_h
        centers = target + dist * back[None, :] + np.array([0.0, elevation, 0.0])
        fwd = -(dist * back + np.array([0.0, elevation, 0.0]))
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        cam = _Camera(centers, right, up, fwd, focal, W / 2, view_h * 0.54)

        camp = cam.to_camera(pos, np.arange(len(self.times)))
        xy = cam.project(camp)
        depth = camp[..., 2]
        scale = focal / np.maximum(depth, cam.near)
        shadow = pos.copy()
        shadow[..., 1] = ground
        shadow_xy = cam.project(cam.to_camera(shadow, np.arange(len(self.times))))

        color = track.color or method_color(track.label, index)
        # depth bands for the grid: full contrast up to just behind the subject, then fading out
        edges = np.array([0.3, dist * 1.25, dist * 1.55, dist * 1.85, dist * 2.2, dist * 2.6])
        grid_bands = list(zip(edges[:-1], edges[1:]))
        fade = [1.0, 0.75, 0.5, 0.3, 0.14]
        grid_colors = [tuple(int(round(f * g + (1 - f) * b)) for g, b in zip(GRID_COLOR, FLOOR_FAR)) for f in fade]
        background = self._background(cam, ground, W, view_h, H)
        if self.show_timeline:
            timeline = self._timeline(track, color, W)
            background.paste(timeline, (0, H - timeline.height))
            self._timeline_top = H - timeline.height
        if track.label:
            ImageDraw.Draw(background).text((14 * S, 12 * S), track.label, font=self._font_label, fill=color)
        head = _find_joint(track.names, r"^head$")
        if head is None:
            head = _find_joint(track.names, r"head")
        if head is not None:
            kids = [int(c) for c in np.nonzero(track.parents == head)[0]]
            head = (head, kids[0] if len(kids) == 1 else None)
        return Panel(
            track=track,
            color=color,
            xy=xy,
            depth=depth,
            shadow_xy=shadow_xy,
            scale=scale,
            camera=cam,
            ground=ground,
            sampled=sampled,
            background=background,
            grid=self._grid(cam, ground, grid_bands, grid_colors, view_h - 1, W),
            side=_sides(track.names, track.parents),
            head=head,
        )

    def _background(self, cam: _Camera, ground: float, W: int, view_h: int, H: int) -> Image.Image:
        """Sky gradient above the horizon and a floor that fades into it (static per panel)."""
        # horizon row: where a point far away along the horizontal forward direction projects
        horiz = np.array([cam.forward[0], 0.0, cam.forward[2]])
        horiz /= np.linalg.norm(horiz)
        cz = float(horiz @ cam.forward)
        cyv = float(horiz @ cam.up)
        horizon = cam.cy - cam.focal * cyv / cz
        rows = np.arange(H, dtype=np.float64)[:, None]
        sky_t = np.clip(rows / max(horizon, 1.0), 0, 1)
        sky = np.array(SKY_TOP) * (1 - sky_t) + np.array(SKY_BOTTOM) * sky_t
        floor_t = np.clip((rows - horizon) / max(view_h - horizon, 1.0), 0, 1) ** 0.7
        floor = np.array(FLOOR_FAR) * (1 - floor_t) + np.array(FLOOR_NEAR) * floor_t
        col = np.where(rows < horizon, sky, floor)
        col[view_h:] = (255, 255, 255)
        img = np.broadcast_to(col[:, None, :], (H, W, 3)).astype(np.uint8)
        self._horizon = horizon
        return Image.fromarray(np.ascontiguousarray(img))

    def _timeline(self, track: Track, color, W: int) -> Image.Image:
        """Static strip under a panel: playback speed over output time on a log scale (0.1x-10x)."""
        S = _SS
        h = self.timeline_h * S
        img = Image.new("RGB", (W, h), (255, 255, 255))
        dr = ImageDraw.Draw(img)
        x0, x1 = 46 * S, W - 12 * S
        y0, y1 = 8 * S, h - 16 * S
        self._tl_geom = (x0, x1, y0, y1)
        dr.rectangle([x0, y0, x1, y1], fill=(246, 248, 250), outline=(222, 226, 232), width=S)

        def ly(v):
            v = np.clip(v, 0.1, 10.0)
            return y1 - (np.log10(v) + 1.0) / 2.0 * (y1 - y0)

        for v, lab in ((10.0, "10x"), (1.0, "1x"), (0.1, "0.1x")):
            y = float(ly(v))
            dr.line([x0, y, x1, y], fill=(200, 206, 214) if v != 1 else (150, 158, 170), width=S)
            dr.text((x0 - 6 * S, y), lab, font=self._font_small, fill=MUTED_TEXT, anchor="rm")
        t = np.arange(track.n_frames) / track.fps
        speed = np.ones(track.n_frames) if track.speed is None else track.speed
        xs = x0 + t / max(self.duration, 1e-9) * (x1 - x0)
        ys = ly(np.maximum(speed, 1e-3))
        dr.line(list(zip(xs.tolist(), ys.tolist())), fill=color, width=2 * S, joint="curve")
        dr.text((x0, h - 2 * S), "playback speed", font=self._font_small, fill=MUTED_TEXT, anchor="ld")
        dr.text((x1, h - 2 * S), f"{track.duration:.2f} s", font=self._font_small, fill=MUTED_TEXT, anchor="rd")
        return img

    # ------------------------------------------------------------------ drawing
    def _grid(self, cam: _Camera, ground: float, bands, colors, y_max: float, x_max: float) -> list:
        """Projected ground-grid segments for every frame, per depth band (computed once).

        The grid is fixed in the world (0.5 m squares) and covers the region the camera looks at
        over the clip; segments are clipped to depth bands whose colour fades into the floor.
        Returns [(colour, segments (N, L, 2, 2), visible (N, L))] per band.
        """
        step = 0.5
        radius = max(4.0, 1.3 * bands[-1][1])  # reaches the end of the last depth band
        c = cam.centers
        look = c + cam.forward[None, :] * ((c[:, 1:2] - ground) / max(-cam.forward[1], 0.05))
        x_lo, x_hi = look[:, 0].min() - radius, look[:, 0].max() + radius
        z_lo, z_hi = look[:, 2].min() - radius, look[:, 2].max() + radius
        xs = np.arange(math.floor(x_lo / step), math.ceil(x_hi / step) + 1) * step
        zs = np.arange(math.floor(z_lo / step), math.ceil(z_hi / step) + 1) * step
        ox, oz = np.ones_like(xs), np.ones_like(zs)
        a = np.concatenate([np.stack([xs, ground * ox, zs[0] * ox], 1), np.stack([xs[0] * oz, ground * oz, zs], 1)])
        b = np.concatenate([np.stack([xs, ground * ox, zs[-1] * ox], 1), np.stack([xs[-1] * oz, ground * oz, zs], 1)])
        frames = np.arange(len(c))
        ca = cam.to_camera(np.broadcast_to(a, (len(c),) + a.shape), frames)  # (N, L, 3)
        cb = cam.to_camera(np.broadcast_to(b, (len(c),) + b.shape), frames)
        dz = cb[..., 2] - ca[..., 2]
        flat = np.abs(dz) < 1e-12
        safe = np.where(flat, 1.0, dz)
        out = []
        for (zlo, zhi), color in zip(bands, colors):
            t_lo = (zlo - ca[..., 2]) / safe
            t_hi = (zhi - ca[..., 2]) / safe
            t0 = np.clip(np.where(dz >= 0, t_lo, t_hi), 0, 1)
            t1 = np.clip(np.where(dz >= 0, t_hi, t_lo), 0, 1)
            inside_flat = flat & (ca[..., 2] > zlo) & (ca[..., 2] < zhi)
            t0 = np.where(flat, 0.0, t0)
            t1 = np.where(flat, np.where(inside_flat, 1.0, 0.0), t1)
            visible = t1 > t0
            p0 = ca + (cb - ca) * t0[..., None]
            p1 = ca + (cb - ca) * t1[..., None]
            s0, s1 = cam.project(p0), cam.project(p1)
            # clip at the bottom of the view (the speed strip lies below it)
            y0, y1 = s0[..., 1], s1[..., 1]
            visible &= (y0 <= y_max) | (y1 <= y_max)
            dy = np.where(np.abs(y1 - y0) < 1e-9, 1e-9, y1 - y0)
            t = np.clip((y_max - y0) / dy, 0.0, 1.0)[..., None]
            s0n = np.where((y0 > y_max)[..., None], s0 + (s1 - s0) * t, s0)
            s1n = np.where((y1 > y_max)[..., None], s0 + (s1 - s0) * t, s1)
            # cull what lies entirely left, right or above the view
            xa, xb = s0n[..., 0], s1n[..., 0]
            visible &= ~(((xa < 0) & (xb < 0)) | ((xa > x_max) & (xb > x_max)) | ((s0n[..., 1] < 0) & (s1n[..., 1] < 0)))
            out.append((color, np.stack([s0n, s1n], axis=-2), visible))
        return out

    def _draw_panel(self, panel: Panel, k: int) -> Image.Image:
        S = _SS
        img = panel.background.copy()
        dr = ImageDraw.Draw(img)
        # ground grid, in depth bands that fade into the floor colour with distance
        for color, segs, visible in panel.grid:
            for a, b in segs[k][visible[k]].tolist():
                dr.line([tuple(a), tuple(b)], fill=color, width=S)
        parents = panel.track.parents
        xy_np = panel.xy[k]
        xy = xy_np.tolist()
        sxy = panel.shadow_xy[k].tolist()
        scale = panel.scale[k]
        bone_w = np.clip(0.045 * scale, 2 * S, 14 * S).astype(int).tolist()
        shadow_w = [int(w * 1.2) for w in bone_w]
        bones = [j for j in range(len(parents)) if parents[j] >= 0]
        # shadow
        for j in bones:
            p = parents[j]
            dr.line([tuple(sxy[p]), tuple(sxy[j])], fill=SHADOW_COLOR, width=shadow_w[j])
        contacts = panel.sampled["contacts"]
        if contacts is not None:
            for j in np.nonzero(contacts[k])[0]:
                x, y = sxy[j]
                r = 0.07 * scale[j]
                dr.ellipse([x - r, y - r * 0.45, x + r, y + r * 0.45], outline=CONTACT_COLOR, width=2 * S)
        # bones, far to near
        base = np.array(panel.color, dtype=np.float64)
        dark = tuple(int(c) for c in base * 0.62)
        light = tuple(int(c) for c in base + (255 - base) * 0.25)
        center = (58, 64, 76)
        side_color = {-1: light, 1: dark, 0: center}
        order = sorted(bones, key=lambda j: -(panel.depth[k, j] + panel.depth[k, parents[j]]))
        for j in order:
            p = parents[j]
            a, b = tuple(xy[p]), tuple(xy[j])
            col = side_color[int(panel.side[j])]
            w = bone_w[j]
            dr.line([a, b], fill=col, width=w)
            r = w / 2
            dr.ellipse([b[0] - r, b[1] - r, b[0] + r, b[1] + r], fill=col)
            dr.ellipse([a[0] - r, a[1] - r, a[0] + r, a[1] + r], fill=col)
        if panel.head is not None:
            h, e = panel.head
            if e is not None:
                # a disc over the head bone (base of the skull to the top of the head)
                x, y = (xy_np[h] + xy_np[e]) / 2
                r = max(0.55 * float(np.hypot(*(xy_np[e] - xy_np[h]))), 0.08 * scale[h])
            else:
                x, y = xy[h]
                r = 0.1 * scale[h]
                y -= 0.07 * scale[h]
            dr.ellipse([x - r, y - r, x + r, y + r], fill=center)
        if contacts is not None:
            for j in np.nonzero(contacts[k])[0]:
                x, y = xy[j]
                r = max(bone_w[j] * 0.75, 3 * S)
                dr.ellipse([x - r, y - r, x + r, y + r], fill=CONTACT_COLOR, outline=(120, 80, 0), width=S)
        self._draw_text(panel, dr, k)
        if self.show_timeline:
            self._draw_cursor(panel, dr, k, self._timeline_top)
        return img

    def _draw_text(self, panel: Panel, dr: ImageDraw.ImageDraw, k: int) -> None:
        S = _SS
        t = self.times[k]
        track = panel.track
        done = t > track.duration + 0.5 / self.fps
        x, y = 14 * S, 12 * S
        if track.label:  # drawn into the background
            y += 24 * S
        tt = min(t, track.duration)
        dr.text((x, y), f"t  {tt:5.2f} s / {track.duration:.2f} s", font=self._font_text, fill=TEXT_COLOR)
        y += 18 * S
        speed = panel.sampled["speed"]
        sp = 1.0 if speed is None else float(speed[k])
        if done:
            line, col = "finished", MUTED_TEXT
        else:
            line = f"speed {sp:5.2f}x"
            col = TEXT_COLOR if 0.67 <= sp <= 1.5 else (190, 60, 40)
        dr.text((x, y), line, font=self._font_text, fill=col)
        if track.source_time is not None:
            y += 18 * S
            dr.text((x, y), f"source  {panel.sampled['source_time'][k]:5.2f} s", font=self._font_text, fill=MUTED_TEXT)

    def _draw_cursor(self, panel: Panel, dr: ImageDraw.ImageDraw, k: int, top: int) -> None:
        S = _SS
        x0, x1, y0, y1 = self._tl_geom
        frac = self.times[k] / max(self.duration, 1e-9)
        x = x0 + frac * (x1 - x0)
        dr.line([x, top + y0 - 2 * S, x, top + y1 + 2 * S], fill=TEXT_COLOR, width=S)

    def frame_image(self, k: int) -> Image.Image:
        """Frame k as a Pillow image at the output size."""
        if not 0 <= k < self.n_frames:
            raise IndexError(k)
        S = _SS
        if len(self.panels) == 1:
            return self._draw_panel(self.panels[0], k).reduce(S)
        out = Image.new("RGB", (self.width, self.height), (255, 255, 255))
        dr = ImageDraw.Draw(out)
        for i, panel in enumerate(self.panels):
            row, col = divmod(i, self.columns)
            x, y = col * self.panel_w, row * self.panel_h
            out.paste(self._draw_panel(panel, k).reduce(S), (x, y))
            if col > 0:
                dr.line([x, y, x, y + self.panel_h], fill=(214, 219, 226), width=1)
            if row > 0:
                dr.line([x, y, x + self.panel_w, y], fill=(214, 219, 226), width=1)
        return out

    def frame(self, k: int) -> np.ndarray:
        return np.asarray(self.frame_image(k))

    def frames(self) -> Iterator[np.ndarray]:
        for k in range(self.n_frames):
            yield self.frame(k)


def _progress(total: int, desc: str, quiet: bool):
    from retime.viz.progress import progress

    return progress(total=total, desc=desc, quiet=quiet, unit="frame")


def render_video(
    tracks: Sequence[Track],
    path: str | os.PathLike,
    fps: float = 30.0,
    panel_size: tuple[int, int] = (480, 540),
    quiet: bool = True,
    **kwargs,
) -> dict:
    """Render ``tracks`` side by side to a video file. Returns {'frames', 'width', 'height', 'fps', 'duration'}."""
    renderer = Renderer(tracks, fps=fps, panel_size=panel_size, **kwargs)
    palette_frames = None
    if os.fspath(path).lower().endswith(".gif"):
        n = renderer.n_frames
        palette_frames = [renderer.frame(k) for k in sorted({0, n // 3, (2 * n) // 3, n - 1})]
    with VideoWriter(path, renderer.width, renderer.height, fps, palette_frames=palette_frames) as writer:
        with _progress(renderer.n_frames, "render", quiet) as bar:
            for k in range(renderer.n_frames):
                writer.write(renderer.frame(k))
                bar.update(1)
    return {
        "frames": renderer.n_frames,
        "width": renderer.width,
        "height": renderer.height,
        "fps": fps,
        "duration": renderer.duration,
    }


def render_still(tracks: Sequence[Track], path: str | os.PathLike, time: float, **kwargs) -> None:
    """Write one frame (at output time ``time``) as a PNG image."""
    renderer = Renderer(tracks, **kwargs)
    k = int(round(np.clip(time, 0, renderer.duration) * renderer.fps))
    from retime.io_util import atomic_write

    with atomic_write(path, "wb") as f:
        renderer.frame_image(min(k, renderer.n_frames - 1)).save(f, format="PNG")


# ---------------------------------------------------------------------- motions
def track_from_motion(motion, label: str = "", curve=None, contacts=None, color=None) -> Track:
    """A Track from a ``retime.motion.Motion`` (FK, converted to metres).

    ``curve``: the timing curve the motion was played through (its speed and source time are
    shown).  ``contacts``: (F, J) bool per frame of ``motion``.
    """
    from retime.motion import end_site_positions, forward_kinematics
    from retime.motion.frame import to_y_up

    skeleton = motion.skeleton
    positions, orientations = forward_kinematics(motion)
    ends = end_site_positions(motion, positions, orientations)
    names = list(skeleton.names)
    parents = list(int(p) for p in skeleton.parents)
    # end sites (toe tips, finger tips, top of the head) are drawn as extra joints
    for j, _ in skeleton.end_sites:
        names.append(f"{skeleton.names[j]}_end")
        parents.append(int(j))
    positions = to_y_up(np.concatenate([positions, ends], axis=1) * float(skeleton.meters_per_unit), skeleton)
    if contacts is not None:
        contacts = np.asarray(contacts, dtype=bool)
        if contacts.shape != (motion.n_frames, skeleton.n_joints):
            raise RetimeError(f"contacts must have shape ({motion.n_frames}, {skeleton.n_joints}), got {contacts.shape}")
        contacts = np.concatenate([contacts, np.zeros((motion.n_frames, ends.shape[1]), dtype=bool)], axis=1)
    speed = source_time = None
    if curve is not None:
        t = np.minimum(np.arange(motion.n_frames) / motion.fps, curve.duration)
        speed = np.asarray(curve.speed(t), dtype=np.float64)
        source_time = np.asarray(curve(t), dtype=np.float64)
    return Track(
        positions,
        np.asarray(parents, dtype=np.int64),
        motion.fps,
        label=label,
        names=names,
        speed=speed,
        source_time=source_time,
        contacts=contacts,
        color=color,
    )
