"""The clips of a batch: files, folders walked for motion files (.bvh, .amc; .fbx, .glb, .gltf with bpy), and jobs files (.csv or .toml) with
per-clip overrides (duration, scale, keytimes, reference, blend, pace)."""
from __future__ import annotations

import csv
import errno
import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath

from ..errors import RetimeError
from ..io_util import file_keys
from ..motion import READABLE
from .layout import BATCH_FILES, OUTPUT_SUFFIXES

MOTION_SUFFIXES = READABLE  # what the single-clip commands read (FBX and glTF with bpy)
JOBS_SUFFIXES = (".csv", ".toml")
JOB_FIELDS = ("motion", "duration", "scale", "keytimes", "reference", "blend", "pace")
GUIDED_FIELDS = ("blend", "pace")  # the fields that are options of guided alone


@dataclass(frozen=True)
class Clip:
    """One clip to retime: its input, where its outputs go (OUTDIR/<name>.bvh, .csv, .json) and
    its timing options (a jobs file's row overrides the command line's)."""

    motion: Path
    name: PurePosixPath  # output path below OUTDIR without suffix, e.g. walks/16_15
    duration: float | None = None
    scale: float | None = None
    keytimes: tuple[tuple[float, float], ...] = ()
    reference: Path | None = None
    blend: float | None = None  # guided's reference influence, 0..1 (None: the method's default)
    pace: float | None = None  # guided's pull to one steady pace, >= 0 (None: the method's default)
    origin: str = ""  # where the clip was named (for error messages): a folder, a jobs file line
    jobs_file: Path | None = None  # the jobs file naming it, if any

    def guided_options(self) -> dict:
        """The guided-only options the clip gives (:data:`GUIDED_FIELDS`; unset ones are left to Settings)."""
        return {k: getattr(self, k) for k in GUIDED_FIELDS if getattr(self, k) is not None}

    def outputs(self, outdir: Path, method: str) -> dict[str, Path]:
        base = outdir / Path(self.name)
        if method == "check":  # a verdict, not a retiming: the report and its plot
            return {"report": base.with_name(base.name + ".json"), "plot": base.with_name(base.name + ".png")}
        paths = {"bvh": base.with_name(base.name + ".bvh"), "warp": base.with_name(base.name + ".csv")}
        if method == "physics":
            paths["report"] = base.with_name(base.name + ".json")
        return paths


@dataclass
class Defaults:
    """The command line's timing options, the default of every clip."""

    duration: float | None = None
    scale: float | None = None
    keytimes: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    reference: Path | None = None


def find_clips(inputs, defaults: Defaults, outdir: Path | None = None,
               skipped: list | None = None) -> list[Clip]:
    """Every clip named by ``inputs``, in order, each with a distinct output name. A folder's walk
    leaves out ``outdir`` (an output folder inside an input folder must not feed the next run), and
    adds to ``skipped`` what it found but cannot read, as (path, reason)."""
    clips: list[Clip] = []
    skipped = [] if skipped is None else skipped
    for text in inputs:
        path = Path(text)
        if path.is_dir():
            clips.extend(_folder_clips(path, defaults, outdir, skipped))
        elif not path.exists():
            raise RetimeError(f"{text}: no such file or folder")
        elif path.suffix.lower() in MOTION_SUFFIXES:
            clips.append(_clip(path, PurePosixPath(path.stem), defaults, origin=str(path)))
        elif path.suffix.lower() == ".csv":
            clips.extend(read_jobs_csv(path, defaults))
        elif path.suffix.lower() == ".toml":
            clips.extend(read_jobs_toml(path, defaults))
        else:
            raise RetimeError(f"{text}: not a motion (.bvh, .amc), a folder or a jobs file (.csv, .toml)")
    if not clips and not skipped:
        raise RetimeError("no clips found: give motion files (.bvh, .amc, or .fbx/.glb/.gltf with bpy), folders holding them, or a jobs file")
    return _distinct_names(clips)


def _distinct_names(clips: list[Clip]) -> list[Clip]:
    """X.amc beside X.bvh (a common layout: the capture and its export) write X.amc.bvh and
    X.bvh.bvh, and so does a clip whose outputs would take a batch file's name (summary.bvh writes
    summary.bvh.csv, not summary.csv); any other two clips with one output name are refused."""
    def key(name):
        return str(name).lower()  # case-insensitive file systems would merge these too

    groups: dict[str, list[Clip]] = {}
    for clip in clips:
        groups.setdefault(key(clip.name), []).append(clip)
    renamed = {}
    for group in groups.values():
        by_suffix: dict[str, Clip] = {}
        for c in group:
            other = by_suffix.setdefault(c.motion.suffix.lower(), c)
            if other is not c:
                raise RetimeError(_clash(other, c))
        if len(group) > 1 or _takes_a_batch_file(group[0].name):
            for c in group:
                renamed[id(c)] = replace(c, name=c.name.with_name(c.name.name + c.motion.suffix.lower()))
    result = [renamed.get(id(c), c) for c in clips]
    seen: dict[str, Clip] = {}
    for clip in result:
        if key(clip.name) in seen:  # e.g. a clip named X.bvh.bvh beside X.bvh and X.amc
            raise RetimeError(_clash(seen[key(clip.name)], clip))
        seen[key(clip.name)] = clip
    return result


def _takes_a_batch_file(name: PurePosixPath) -> bool:
    return str(name.parent) == "." and any((name.name + s).lower() in BATCH_FILES for s in OUTPUT_SUFFIXES)


def _clash(a: Clip, b: Clip) -> str:
    if a.origin != b.origin and a.motion.parent != b.motion.parent:
        advice = ("give one folder that holds both (each keeps its subfolder in OUTDIR), "
                  "or run them into different output folders")
    else:
        advice = "rename one"
    return f"{a.motion} ({a.origin}) and {b.motion} ({b.origin}) would both write {b.name}.bvh; {advice}"


def _folder_clips(folder: Path, defaults: Defaults, outdir: Path | None, skipped: list) -> list[Clip]:
    """The motion files below ``folder``; what cannot be read (a folder, a dangling or looping
    symlink) goes to ``skipped`` as (path, reason)."""
    root = folder.resolve()
    skip = outdir.resolve() if outdir is not None else None
    if skip == root:
        raise RetimeError(f"{folder}: is also the output folder; the outputs would land on the inputs "
                          "(choose another -o)")
    if skip is not None and not skip.is_relative_to(root):
        skip = None  # OUTDIR outside this folder: nothing of it is in the walk

    def unreadable(e: OSError):
        skipped.append((e.filename, f"cannot read this folder ({e.strerror}); its clips were not run"))

    found = []
    for top, dirs, files in os.walk(folder, onerror=unreadable):
        if skip is not None and Path(top).resolve().is_relative_to(skip):
            dirs.clear()
            continue
        dirs.sort()
        for name in files:
            p = Path(top) / name
            if p.suffix.lower() not in MOTION_SUFFIXES:
                continue
            problem = _not_a_file(p)
            if problem:
                skipped.append((str(p), problem))
            else:
                found.append(p)
    return [_clip(p, PurePosixPath(p.relative_to(folder).with_suffix("").as_posix()), defaults, origin=str(folder))
            for p in sorted(found)]


def _not_a_file(path: Path) -> str | None:
    try:
        if path.is_file():
            return None
    except OSError as e:  # a symlink loop (ELOOP), ...
        return f"cannot read it ({e.strerror})"
    if path.is_symlink():
        try:
            path.stat()
        except OSError as e:
            if e.errno == errno.ELOOP:
                return "a symlink that loops; not run"
            return f"a symlink to {os.readlink(path)}, which does not exist; not run"
    return "not a regular file; not run"


def _clip(motion: Path, name: PurePosixPath, defaults: Defaults, origin: str, **overrides) -> Clip:
    fields = {"duration": defaults.duration, "scale": defaults.scale, "keytimes": tuple(defaults.keytimes),
              "reference": defaults.reference}
    if overrides.get("duration") is not None or overrides.get("scale") is not None:
        fields["duration"] = fields["scale"] = None  # a row's duration replaces the command's scale, and back
    fields.update({k: v for k, v in overrides.items() if v is not None})
    return Clip(motion=motion, name=name, origin=origin, **fields)


def _job_name(motion: Path, jobs_file: Path) -> PurePosixPath:
    """Mirror the jobs file's folder; a clip outside it goes to OUTDIR's top."""
    try:
        return PurePosixPath(motion.resolve().relative_to(jobs_file.parent.resolve()).with_suffix("").as_posix())
    except ValueError:
        return PurePosixPath(motion.stem)


def _job_clip(row: dict, where: str, jobs_file: Path, defaults: Defaults) -> Clip:
    unknown = sorted(set(row) - set(JOB_FIELDS))
    if unknown:
        raise RetimeError(f"{where}: unknown field {unknown[0]!r}; a clip may give {', '.join(JOB_FIELDS)}")
    motion_text = _text(row.get("motion"), "motion", where)
    if not motion_text:
        raise RetimeError(f"{where}: no motion given")
    motion = jobs_file.parent / motion_text  # relative to the jobs file, as a user reads it
    duration = _positive(row.get("duration"), "duration", where)
    scale = _positive(row.get("scale"), "scale", where)
    if duration is not None and scale is not None:
        raise RetimeError(f"{where}: give duration or scale, not both")
    keytimes = parse_keytimes(row.get("keytimes"), where)
    reference_text = _text(row.get("reference"), "reference", where)
    reference = jobs_file.parent / reference_text if reference_text else None
    blend = _unit(row.get("blend"), "blend", where)
    pace = _non_negative(row.get("pace"), "pace", where)
    return _clip(motion, _job_name(motion, jobs_file), defaults, origin=where, duration=duration, scale=scale,
                 keytimes=keytimes or None, reference=reference, blend=blend, pace=pace, jobs_file=jobs_file)


def read_jobs_csv(path: Path, defaults: Defaults) -> list[Clip]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise RetimeError(f"{path}: cannot read the jobs file: {e}") from None
    reader = csv.reader(text.splitlines())
    try:
        rows = list(reader)
    except csv.Error as e:  # e.g. a cell over the csv module's 131,072 characters
        raise RetimeError(f"{path} line {reader.line_num}: not a readable CSV row ({e}); "
                          "a jobs file holds paths and numbers") from None
    if not rows or [h.strip().lower() for h in rows[0]][:1] != ["motion"]:
        raise RetimeError(f"{path}: a jobs file starts with a header like 'motion,duration,scale,keytimes,reference'")
    header = [h.strip().lower() for h in rows[0]]
    twice = sorted({h for h in header if h and header.count(h) > 1})
    if twice:
        raise RetimeError(f"{path} line 1: the column {twice[0]!r} is given twice; keep one")
    clips = []
    for lineno, cells in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in cells):
            continue
        if len(cells) > len(header):
            raise RetimeError(f"{path} line {lineno}: {len(cells)} cells for {len(header)} columns")
        row = {h: c.strip() for h, c in zip(header, cells) if c.strip()}
        clips.append(_job_clip(row, f"{path} line {lineno}", path, defaults))
    return clips


def read_jobs_toml(path: Path, defaults: Defaults) -> list[Clip]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise RetimeError(f"{path}: cannot read the jobs file: {e}") from None
    except tomllib.TOMLDecodeError as e:
        raise RetimeError(f"{path}: not valid TOML: {e}") from None
    tables = data.get("clip")
    if not isinstance(tables, list) or set(data) - {"clip"}:
        raise RetimeError(f"{path}: a jobs file holds [[clip]] tables (motion = \"walk.bvh\", duration = 2, ...)")
    clips = []
    for i, table in enumerate(tables, start=1):
        if not isinstance(table, dict):
            raise RetimeError(f"{path} clip {i}: not a table")
        clips.append(_job_clip(table, f"{path} clip {i}", path, defaults))
    return clips


def _text(value, name, where) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str):
        raise RetimeError(f"{where}: {name} must be a text (a path), got {value!r}")
    if "\0" in value:
        raise RetimeError(f"{where}: {name} holds a NUL byte; a path cannot")
    return value.strip() or None


def _number(value, name, where, ok, what) -> float | None:
    """A cell's number (None if empty), required to satisfy ``ok`` (``what`` says how)."""
    if value is None or value == "":
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RetimeError(f"{where}: {name} {value!r} is not a number") from None
    if isinstance(value, bool) or not ok(v):
        raise RetimeError(f"{where}: {name} must be {what}, got {value!r}")
    return v


def _positive(value, name, where) -> float | None:
    return _number(value, name, where, lambda v: v > 0 and math.isfinite(v), "a positive number")


def _non_negative(value, name, where) -> float | None:
    return _number(value, name, where, lambda v: v >= 0 and math.isfinite(v), "a finite number >= 0")


def _unit(value, name, where) -> float | None:
    return _number(value, name, where, lambda v: 0.0 <= v <= 1.0, "a number from 0 to 1")


def parse_keytimes(value, where) -> tuple[tuple[float, float], ...]:
    """'1.2=0.8;2=1.5' (or a TOML list of 'SRC=DST' texts) -> ((1.2, 0.8), (2.0, 1.5))."""
    if value is None or value == "":
        return ()
    items = value if isinstance(value, list) else str(value).split(";")
    pairs = []
    for item in items:
        if not isinstance(item, str):
            raise RetimeError(f"{where}: keytimes must look like '1.2=0.8;2=1.5', got {value!r}")
        if not item.strip():
            continue
        src, sep, dst = item.partition("=")
        try:
            pair = (float(src), float(dst))
        except ValueError:
            pair = None
        if not sep or pair is None or not all(math.isfinite(x) for x in pair):
            raise RetimeError(f"{where}: keytime must look like SRC=DST in seconds (e.g. 1.2=0.8), got {item.strip()!r}")
        pairs.append(pair)
    return tuple(pairs)


def files_read(motion: Path) -> list[Path]:
    """The files a motion's load reads: the motion and, for an .amc, the .asf found beside it."""
    files = [motion]
    if motion.suffix.lower() == ".amc":
        from ..motion.asf import find_asf

        try:
            files.append(find_asf(motion))
        except Exception:  # no skeleton: the clip will fail and say so
            pass
    return files


def check_inputs_kept(clips: list[Clip], outdir: Path, method: str) -> None:
    """Refuse a batch that would write over one of its inputs: a clip's motion, skeleton or
    reference, or a jobs file, whatever the layout (by path, symlink or hard link). ``outdir``'s
    own files count as outputs too."""
    inputs: dict = {}
    for clip in clips:
        named = [(p, f"an input ({clip.origin})") for p in files_read(clip.motion)]
        if clip.reference is not None:
            named += [(p, f"a reference ({clip.origin})") for p in files_read(clip.reference)]
        if clip.jobs_file is not None:
            named.append((clip.jobs_file, "the jobs file"))
        for path, what in named:
            for key in file_keys(path):
                inputs.setdefault(key, (path, what))
    outputs = [outdir / name for name in BATCH_FILES]
    outputs += [p for clip in clips for p in clip.outputs(outdir, method).values()]
    for output in outputs:
        hit = next((inputs[key] for key in file_keys(output) if key in inputs), None)
        if hit is not None:
            raise RetimeError(f"{output}: would overwrite {hit[1]} {hit[0]}; choose an output folder apart from the inputs")


def with_absolute_paths(clip: Clip) -> Clip:
    """Workers may run in another folder: send them absolute paths."""
    return replace(clip, motion=clip.motion.absolute(),
                   reference=clip.reference.absolute() if clip.reference else None)
