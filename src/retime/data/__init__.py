"""Small CMU clips bundled with retime (see cmu/README.md for attribution)."""
from pathlib import Path

CMU_DIR = Path(__file__).resolve().parent / "cmu"


def bundled_path(name: str) -> Path:
    """Path of a bundled clip, e.g. ``bundled_path("16_06.amc")``."""
    path = CMU_DIR / name
    if not path.exists():
        available = ", ".join(sorted(p.name for p in CMU_DIR.iterdir() if p.suffix != ".md"))
        raise FileNotFoundError(f"no bundled clip {name!r}; bundled clips: {available}")
    return path
