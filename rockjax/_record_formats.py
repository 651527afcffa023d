"""Readers of two strong-motion database formats, and the names of formats not read.

- **ESM** (``format="esm"``): the ASCII files of the Engineering Strong Motion database
  (esm.mi.ingv.it): header lines ``KEY: value``, among them
  ``SAMPLING_INTERVAL_S``, ``NDATA``, ``DATA_TYPE`` (ACCELERATION) and ``UNITS``
  (``cm/s^2``), the last one ``USER5:``; then the values, any number per line.
- **K-NET / KiK-net** (``format="knet"``): NIED's ASCII files (``.EW``, ``.NS``,
  ``.UD``, KiK-net's ``.EW1``, ``.NS2``, ...): 17 header lines (``Origin Time``, ...,
  ``Sampling Freq(Hz)  100Hz``, ``Scale Factor  3920(gal)/6182761``, ``Max. Acc. (gal)``,
  ``Last Correction``, ``Memo.``), then integer counts, 8 per line. The acceleration in
  gal is counts x scale factor, less its mean (NIED's instruction: the counts carry an
  offset); the header's ``Max. Acc. (gal)`` is checked against the result (or against the
  counts x scale factor, should a file state the peak before the mean is removed).

Both give (dt [s], values, units of the values, description). Formats recognised but
not read are named by `unsupported_format`.
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["is_esm", "is_knet", "read_esm", "read_knet", "unsupported_format"]

_KNET_HEADER_LINES = 17
_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"


def is_esm(lines: list[str]) -> bool:
    """Whether `lines` are an ESM ASCII file (a ``SAMPLING_INTERVAL_S:`` and an ``NDATA:``
    line among the first 80)."""
    head = [line.strip().upper() for line in lines[:80]]
    return (any(h.startswith("SAMPLING_INTERVAL_S:") for h in head)
            and any(h.startswith("NDATA:") for h in head))


def is_knet(lines: list[str]) -> bool:
    """Whether `lines` are a K-NET/KiK-net ASCII file (``Origin Time`` first and a
    ``Scale Factor`` line in the header)."""
    return (bool(lines) and lines[0].strip().startswith("Origin Time")
            and any(line.startswith("Scale Factor") for line in lines[:_KNET_HEADER_LINES]))


def _values(lines, start: int, source: str) -> list[float]:
    out: list[float] = []
    for lineno, line in enumerate(lines[start:], start=start + 1):
        for tok in line.split():
            if not re.fullmatch(_NUM, tok):
                raise ValueError(f"{source}, line {lineno}: non-numeric data in data "
                                 f"section: {line.strip()[:80]!r}")
            out.append(float(tok))
    return out


def _esm_header(lines, source):
    """(the header's KEY -> value, the index of the first data line)."""
    header: dict[str, str] = {}
    for i, line in enumerate(lines):
        m = re.match(r"\s*([A-Z0-9_/^.()\-]+)\s*:(.*)$", line)
        if m is None:
            return header, i
        header[m.group(1).upper()] = m.group(2).strip()
        if m.group(1).upper() == "USER5":
            return header, i + 1
    raise ValueError(f"{source}: an ESM header without data")


def read_esm(lines: list[str], source: str):
    """(dt [s], values in the file's units, the units as written, description) of an
    ESM ASCII file; ValueError naming the file for a missing or bad key, a record that is
    not an acceleration, or an NDATA that does not match the values."""
    header, start = _esm_header(lines, source)
    for key in ("SAMPLING_INTERVAL_S", "NDATA", "UNITS"):
        if not header.get(key):
            raise ValueError(f"{source}: ESM header without {key}")
    kind = " ".join(header.get("DATA_TYPE", "ACCELERATION").upper().split())
    if kind != "ACCELERATION":
        raise ValueError(f"{source}: the ESM file holds DATA_TYPE {kind}; rockjax reads "
                         "acceleration records (DATA_TYPE: ACCELERATION)")
    try:
        dt = float(header["SAMPLING_INTERVAL_S"])
        npts = int(float(header["NDATA"]))
    except ValueError:
        raise ValueError(f"{source}: ESM header: SAMPLING_INTERVAL_S "
                         f"{header['SAMPLING_INTERVAL_S']!r} or NDATA {header['NDATA']!r} "
                         "is not a number") from None
    values = _values(lines, start, source)
    if len(values) != npts:
        raise ValueError(f"{source}: the ESM header says NDATA: {npts} but {len(values)} "
                         "values were found")
    description = "\n".join(line.rstrip() for line in lines[:start])
    return dt, np.asarray(values), header["UNITS"], description


def _knet_field(lines, name: str, source: str) -> str:
    for line in lines[:_KNET_HEADER_LINES]:
        if line.startswith(name):
            return line[len(name):].strip()
    raise ValueError(f"{source}: K-NET header without {name!r}")


def read_knet(lines: list[str], source: str):
    """(dt [s], acceleration in gal, ``"gal"``, description) of a K-NET/KiK-net ASCII
    file; ValueError naming the file for a bad header or data that do not match its
    ``Max. Acc. (gal)``."""
    freq = _knet_field(lines, "Sampling Freq(Hz)", source)
    scale = _knet_field(lines, "Scale Factor", source)
    m_freq = re.fullmatch(rf"({_NUM})\s*Hz", freq)
    m_scale = re.fullmatch(rf"({_NUM})\s*\(gal\)\s*/\s*({_NUM})", scale)
    if m_freq is None or m_scale is None:
        raise ValueError(f"{source}: K-NET header: cannot read 'Sampling Freq(Hz) {freq}' "
                         f"or 'Scale Factor {scale}' (expected e.g. 100Hz, 3920(gal)/6182761)")
    dt = 1.0 / float(m_freq.group(1))
    counts = np.asarray(_values(lines, _KNET_HEADER_LINES, source))
    if counts.size < 2:
        raise ValueError(f"{source}: a record needs at least 2 samples, found {counts.size}")
    raw = counts * (float(m_scale.group(1)) / float(m_scale.group(2)))
    gal = raw - raw.mean()
    peak = re.match(_NUM, _knet_field(lines, "Max. Acc. (gal)", source))
    if peak is not None and float(peak.group(0)) > 0:
        stated, got = float(peak.group(0)), float(np.max(np.abs(gal)))
        # the stated peak is of the data less their mean; the raw peak is accepted too
        if min(abs(got - stated), abs(float(np.max(np.abs(raw))) - stated)) > (
                0.05 * stated + 0.01):
            raise ValueError(f"{source}: the K-NET header says Max. Acc. {stated:g} gal but "
                             f"the data give {got:.6g} gal (counts x scale factor, mean "
                             "removed); the file may be damaged")
    description = "\n".join(line.rstrip() for line in lines[:_KNET_HEADER_LINES])
    description += "\n(rockjax: counts x scale factor, mean removed)"
    return dt, gal, "gal", description


#: (test on the first lines, the format's name) of text formats recognised but not read
_UNSUPPORTED = (
    (lambda head: "COSMOS" in head[0].upper() if head else False,
     "COSMOS strong-motion format (V1/V2)"),
    (lambda head: bool(head) and head[0].upper().startswith(("CORRECTED ACCELEROGRAM",
                                                             "UNCORRECTED ACCELEROGRAM")),
     "USGS/CSMIP (V2) format"),
    (lambda head: any(h.strip().upper().startswith(("<?XML", "<QUAKEML")) for h in head[:2]),
     "an XML file"),
    (lambda head: bool(head) and head[0].lstrip().startswith(("{", "[")),
     "a JSON file"),
)


def unsupported_format(lines: list[str]) -> str | None:
    """The name of a known format that rockjax does not read, or None."""
    head = [line for line in lines[:5] if line.strip()]
    for test, name in _UNSUPPORTED:
        if test(head):
            return name
    return None
