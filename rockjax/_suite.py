"""A suite of ground-motion record files: files and folders (a folder gives every record
file in it, sorted by name), each with the units given for it, and unique labels; what
`rockjax sweep` and `rockjax fragility` read their `--record`s through."""

from __future__ import annotations

import dataclasses
import pathlib

from ._errors import ParameterError
from ._units import UNITS

#: the files a folder gives (by suffix, case-insensitive); others are skipped
RECORD_SUFFIXES = (".at2", ".dat", ".txt", ".csv", ".acc", ".asc", ".gz",  # .asc: ESM
                   *(f".{c}{n}" for c in ("ew", "ns", "ud") for n in ("", "1", "2")))  # K-NET


@dataclasses.dataclass
class RecordFile:
    """One record to read: its path, the units given for it (None: the file's own, or a
    default), and the folder it came from (None: named itself)."""

    path: str
    units: str | None = None
    folder: str | None = None


def split_record_units(text):
    """(path, units or None) of a record named "FILE:UNITS": a trailing `:UNIT` naming a
    unit of acceleration of `rockjax.UNITS` (`:g`, `:m/s2`, `:cm/s2`, `:gal`, also
    `:m/s^2`, `:mps2`, ...) names the record's units (canonical name); any other colon
    belongs to the path, and so does the suffix when the whole text names an existing
    file."""
    head, sep, tail = str(text).rpartition(":")
    units = None
    if sep and UNITS.kind_of(tail) == "acceleration":
        units = UNITS.normalize(tail, "acceleration")
    if units is None or not head or pathlib.Path(text).exists():
        return str(text), None
    return head, units


def _folder_files(spec: RecordFile):
    """(the record files of a folder, sorted, as RecordFiles; the names skipped)."""
    files = sorted(p for p in pathlib.Path(spec.path).iterdir()
                   if p.is_file() and not p.name.startswith("."))
    taken = [p for p in files if p.suffix.lower() in RECORD_SUFFIXES]
    skipped = [p.name for p in files if p.suffix.lower() not in RECORD_SUFFIXES]
    if not taken:
        raise ParameterError(f"no record files in this folder (looked for "
                             f"{', '.join(RECORD_SUFFIXES)}; found "
                             f"{', '.join(skipped) or 'nothing'})", param="records",
                             value=spec.path)
    return [RecordFile(str(p), spec.units, spec.path) for p in taken], skipped


def expand_folders(specs):
    """`RecordFile`s with the folders replaced by their record files (a file also named
    itself takes the units given there; each file once). Returns (files, {folder: names
    skipped}); a `ParameterError` about `records` for a file named twice or a folder with
    no record files."""
    named = {}
    for spec in specs:
        if not pathlib.Path(spec.path).is_dir():
            key = pathlib.Path(spec.path).resolve()
            if key in named:
                raise ParameterError("given twice", param="records", value=spec.path)
            named[key] = spec
    out, skipped, seen = [], {}, set()
    for spec in specs:
        files = [spec]
        if pathlib.Path(spec.path).is_dir():
            files, skipped[spec.path] = _folder_files(spec)
        for f in files:
            key = pathlib.Path(f.path).resolve()
            if key not in seen:
                seen.add(key)
                own = named.get(key)
                out.append(f if own is None else dataclasses.replace(own, folder=f.folder))
    return out, skipped


def unique_labels(paths):
    """File stems as labels; the path as given where stems collide, then a #k suffix."""
    stems = [pathlib.Path(p).stem for p in paths]
    labels = [str(p) if stems.count(s) > 1 else s for p, s in zip(paths, stems)]
    return [f"{lab}#{labels[:i].count(lab) + 1}" if labels.count(lab) > 1 else lab
            for i, lab in enumerate(labels)]
