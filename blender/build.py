"""Build the Blender extension: ``python3 blender/build.py`` -> ``dist/retime-addon-VERSION.zip``.

The zip holds ``blender/retime_addon/`` and the armature module it shares with retime's FBX/glTF bridge
(``src/retime/motion/inside_blender/armature.py``), laid out as Blender's extension format wants: the
manifest and ``__init__.py`` at the top. Install it with Edit > Preferences > Get Extensions > Install
from Disk, or ``blender --command extension install-file -r user_default -e dist/retime-addon-VERSION.zip``.
"""
import argparse
import re
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ADDON = HERE / "retime_addon"
SHARED = HERE.parent / "src" / "retime" / "motion" / "inside_blender" / "armature.py"


def version() -> str:
    match = re.search(r'^version\s*=\s*"([^"]+)"', (ADDON / "blender_manifest.toml").read_text(), re.M)
    if match is None:
        sys.exit(f"{ADDON / 'blender_manifest.toml'}: no version line")
    return match.group(1)


def build(out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"retime-addon-{version()}.zip"
    files = sorted(p for p in ADDON.rglob("*") if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc")
    tmp = target.with_suffix(".zip.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for path in files:
            z.write(path, path.relative_to(ADDON).as_posix())
        z.write(SHARED, "armature.py")
    tmp.replace(target)
    return target


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("-o", "--output-dir", type=Path, default=HERE.parent / "dist", help="default: dist/")
    args = parser.parse_args(argv)
    print(build(args.output_dir))


if __name__ == "__main__":
    main()
