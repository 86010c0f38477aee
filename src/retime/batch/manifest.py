"""OUTDIR/.retime-batch.json: for every finished clip, a SHA-256 of what made its outputs (the input's
bytes, its skeleton's and reference's bytes, the method and every option). A re-run skips a clip
whose hash still matches and whose outputs exist."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..io_util import atomic_write
from .jobs import Clip

MANIFEST_NAME = ".retime-batch.json"
FORMAT = 1


def _files_read(motion: Path) -> list[Path]:
    """The files a motion's load reads: the motion and, for an .amc, the .asf found beside it."""
    files = [motion]
    if motion.suffix.lower() == ".amc":
        from ..motion.asf import find_asf

        try:
            files.append(find_asf(motion))
        except Exception:  # no skeleton: the clip will fail and say so; its hash only has to differ
            pass
    return files


def clip_hash(clip: Clip, method: str, options: dict) -> str | None:
    """The clip's fingerprint, or None when an input cannot be read (the clip then always runs)."""
    h = hashlib.sha256()
    settings = {"method": method, "duration": clip.duration, "scale": clip.scale,
                "keytimes": [list(k) for k in clip.keytimes], "options": options}
    if clip.blend is not None:  # only when given: the fingerprints of earlier batches stay as they were
        settings["blend"] = clip.blend
    h.update(json.dumps(settings, sort_keys=True).encode())
    files = _files_read(clip.motion) + (_files_read(clip.reference) if clip.reference else [])
    for path in files:
        try:
            data = path.read_bytes()
        except OSError:
            return None
        h.update(b"\0file %d\0" % len(data))  # lengths keep (ab, c) and (a, bc) apart
        h.update(data)
    return h.hexdigest()


class Manifest:
    def __init__(self, outdir: Path):
        self.path = outdir / MANIFEST_NAME
        self.clips: dict[str, dict] = {}
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            if isinstance(data, dict) and data.get("format") == FORMAT and isinstance(data.get("clips"), dict):
                self.clips = data["clips"]
        except (OSError, ValueError):  # none yet, or unreadable: every clip runs
            pass

    def is_current(self, clip: Clip, digest: str | None, outputs: dict[str, Path]) -> bool:
        entry = self.clips.get(str(clip.name))
        return (digest is not None and isinstance(entry, dict) and entry.get("hash") == digest
                and all(p.is_file() for p in outputs.values()))

    def record(self, clip: Clip, digest: str | None, seconds: float) -> None:
        if digest is None:
            self.forget(clip)
        else:
            self.clips[str(clip.name)] = {"input": str(clip.motion), "hash": digest, "seconds": round(seconds, 3)}

    def forget(self, clip: Clip) -> None:
        self.clips.pop(str(clip.name), None)

    def save(self) -> None:
        text = json.dumps({"format": FORMAT, "clips": self.clips}, indent=1, sort_keys=True)
        with atomic_write(self.path) as f:
            f.write(text + "\n")
