"""OUTDIR/.retime-batch.json: for every finished clip, a SHA-256 of what made its outputs (the input's
bytes, its skeleton's and reference's bytes, the method and every option). A re-run skips a clip
whose hash still matches and whose outputs exist."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..errors import RetimeError
from ..io_util import atomic_write
from .jobs import Clip, files_read
from .layout import MANIFEST_NAME

FORMAT = 1


def clip_hash(clip: Clip, method: str, options: dict) -> str | None:
    """The clip's fingerprint, or None when an input cannot be read (the clip then always runs)."""
    h = hashlib.sha256()
    settings = {"method": method, "duration": clip.duration, "scale": clip.scale,
                "keytimes": [list(k) for k in clip.keytimes], "options": options}
    settings.update(clip.guided_options())  # only when given: the fingerprints of earlier batches stay as they were
    h.update(json.dumps(settings, sort_keys=True).encode())
    files = files_read(clip.motion) + (files_read(clip.reference) if clip.reference else [])
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
        self.method: str | None = None  # the method whose outputs the folder holds (None: not known)
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            if isinstance(data, dict) and data.get("format") == FORMAT and isinstance(data.get("clips"), dict):
                self.clips = data["clips"]
                self.method = data.get("method") if isinstance(data.get("method"), str) else None
        except (OSError, ValueError):  # none yet, or unreadable: every clip runs
            pass

    def claim(self, method: str) -> None:
        """Refuse a folder holding another method's outputs (their files share names: a check report
        would replace a physics report beside its motion, and a summary would mix the two); else the
        folder is ``method``'s from the manifest's first save on, so a batch killed mid-run keeps it."""
        if self.clips and self.method is not None and self.method != method:
            raise RetimeError(f"{self.path.parent}: holds the outputs of a --method {self.method} batch "
                              f"(see {self.path.name}); write the {method} batch to another folder")
        self.method = method

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
        text = json.dumps({"format": FORMAT, "method": self.method, "clips": self.clips}, indent=1, sort_keys=True)
        with atomic_write(self.path) as f:
            f.write(text + "\n")
