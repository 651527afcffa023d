"""Reading the text of a data file: gzip, encodings, delimiters and decimal commas.

Shared by the record reader (`rockjax.read_record`) and the decay-trace reader
(`identification.read_trace`, through `rockjax.datasets`), so that both accept the same
files:

- **gzip**: a file that starts with gzip's magic bytes (whatever its name; usually
  ``.gz``) is decompressed first.
- **encoding**: UTF-8, with or without a byte-order mark (Excel's); bytes that are not
  UTF-8 are replaced (they can only be in header text).
- **delimiters**: ``;``, tabs, commas or blanks between the values of a row, detected
  from the rows of numbers.
- **decimal commas** (European CSV: ``0,01;-0,5``): detected when the values are separated
  by ``;``, tabs or blanks and hold a comma where a point belongs.

Binary files that rockjax cannot read (zip, Excel workbooks, SAC, miniSEED, HDF5) are
named as such (`binary_kind`) rather than parsed as text.
"""

from __future__ import annotations

import dataclasses
import gzip
import os
import re

__all__ = ["Dialect", "binary_kind", "normalize_rows", "read_text", "sniff"]

_GZIP_MAGIC = b"\x1f\x8b"
#: leading bytes of binary formats that are not read, and what they are
_BINARY = (
    (b"PK\x03\x04", "a zip archive (or an Excel .xlsx workbook); extract it, or export "
                    "the sheet as CSV"),
    (b"\xd0\xcf\x11\xe0", "an Excel .xls workbook; export the sheet as CSV"),
    (b"\x89HDF", "an HDF5 file"),
    (b"BZh", "a bzip2 archive; decompress it (gzip files are read directly)"),
    (b"\xfd7zXZ", "an xz archive; decompress it (gzip files are read directly)"),
)
_DECIMAL_COMMA_RE = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?")
_INT_RE = re.compile(r"[+-]?\d+")
_DATA_START_RE = re.compile(r"[+-]?(?:\d|[.,]\d)")
_DATA_CHARS_RE = re.compile(r"[0-9eEdD+\-.,;\s]+")  # a row of numbers, no words


def binary_kind(raw: bytes) -> str | None:
    """What a binary file is (a phrase such as ``"an HDF5 file"``), or None for text.

    Text is any file whose first 4 KiB hold no NUL byte; a file with NUL bytes is named by
    its magic bytes when known (zip, Excel, HDF5, bzip2, xz), else as "a binary file (SAC,
    miniSEED or another binary format)"."""
    for magic, what in _BINARY:
        if raw.startswith(magic):
            return what
    if b"\x00" in raw[:4096]:
        return "a binary file (SAC, miniSEED or another binary format)"
    return None


def read_text(path) -> tuple[str, bool]:
    """(the text of the file at `path` (str, os.PathLike or an importlib.resources
    Traversable), whether it was gzip-compressed).

    gzip is recognised by its magic bytes; text is decoded as UTF-8 (a byte-order mark is
    dropped, bytes that are not UTF-8 are replaced). Raises ValueError naming the file for
    a gzip file that is damaged and for binary formats (`binary_kind`); OSError as `open`.
    """
    if isinstance(path, (str, os.PathLike)):
        with open(path, "rb") as f:
            raw = f.read()
    else:  # an importlib.resources Traversable
        raw = path.read_bytes()
    compressed = raw.startswith(_GZIP_MAGIC)
    if compressed:
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as e:
            raise ValueError(f"{os.fspath(path)}: a damaged gzip file ({e})") from None
    kind = binary_kind(raw)
    if kind is not None:
        inner = "a gzip-compressed file holding " if compressed else ""
        raise ValueError(f"{os.fspath(path)}: unsupported format: {inner}{kind}, not text")
    return raw.decode("utf-8-sig", errors="replace"), compressed


@dataclasses.dataclass(frozen=True)
class Dialect:
    """How the rows of a text table are written: `delimiter` (``";"``, ``","``, or None
    for blanks and tabs) and whether the values use a `decimal_comma`."""

    delimiter: str | None = None
    decimal_comma: bool = False

    @property
    def note(self) -> str:
        """A few words for a record's or trace's description ("" for plain CSV)."""
        parts = []
        if self.delimiter == ";":
            parts.append("';'-separated")
        if self.decimal_comma:
            parts.append("decimal commas")
        return ", ".join(parts)

    def split(self, line: str) -> list[str]:
        """The fields of `line`, stripped, decimal commas turned into points."""
        s = line.strip()
        if self.delimiter is None:
            fields = s.split()
        else:
            fields = [f.strip() for f in s.split(self.delimiter)]
            if self.delimiter == ";" and fields and fields[-1] == "":
                fields = fields[:-1]  # a trailing ';'
        if self.decimal_comma:
            fields = [f.replace(",", ".") if _DECIMAL_COMMA_RE.fullmatch(f) else f
                      for f in fields]
        return fields


def _data_rows(lines: list[str], limit: int = 200) -> list[str]:
    rows = []
    for line in lines:
        s = line.strip()
        if s and _DATA_START_RE.match(s) and _DATA_CHARS_RE.fullmatch(s):
            rows.append(s)
            if len(rows) >= limit:
                break
    return rows


def sniff(lines: list[str]) -> Dialect:
    """The `Dialect` of the rows of numbers among `lines` (those that start with a digit,
    a sign or a point and hold only numbers and separators):

    - ``;`` when every row of more than one field holds one (the last row of an AT2 file
      may hold a single value), with decimal commas if any value has one;
    - blanks (and tabs) with decimal commas when every blank-separated field is a number
      with a decimal comma (``0,01 -0,5``) or an integer, and some have one;
    - commas when every row holds one;
    - else blanks (decimal commas when some value has one and none has a point).
    """
    rows = _data_rows(lines)
    if not rows:
        return Dialect()
    if any(";" in r for r in rows) and all(";" in r or len(r.split()) == 1 for r in rows):
        fields = [f.strip() for r in rows for f in r.split(";") if f.strip()]
        return Dialect(";", any(_DECIMAL_COMMA_RE.fullmatch(f) for f in fields))
    blank = [f for r in rows for f in r.split()]
    if (any("," in r for r in rows) and any(_DECIMAL_COMMA_RE.fullmatch(f) for f in blank)
            and all(_DECIMAL_COMMA_RE.fullmatch(f) or _INT_RE.fullmatch(f) for f in blank)):
        return Dialect(None, True)
    if all("," in r for r in rows):
        return Dialect(",", False)
    return Dialect(None, any(_DECIMAL_COMMA_RE.fullmatch(f) for f in blank)
                   and not any("." in f for f in blank))


def normalize_rows(lines: list[str], sep: str = " ") -> tuple[list[str], Dialect]:
    """(`lines` with every row that is not a comment (``#``) rewritten as its fields joined
    by `sep`, with decimal points; the `Dialect` found). Files whose rows are already
    separated by `sep` (or, for ``sep=" "``, by blanks or commas) with decimal points come
    back unchanged, and so do files without a row of numbers only (rows with a text
    column, which only comma-separated traces may have)."""
    if not _data_rows(lines, limit=1):  # no row of numbers only (a text column): as is
        return lines, Dialect()
    dialect = sniff(lines)
    plain = dialect.delimiter != ";" and not dialect.decimal_comma
    if plain and (sep == " " or dialect.delimiter == sep):
        return lines, dialect
    out = []
    for line in lines:
        s = line.strip()
        out.append(line if not s or s.startswith("#") else sep.join(dialect.split(s)))
    return out, dialect
