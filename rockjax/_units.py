"""The one table of units that rockjax reads: records, decay traces and the command line.

Every quantity rockjax computes with is in SI (m, m/s², s). Files and arguments may state
other units; this module converts them. The table, by kind (canonical name: size in SI):

- ``"length"`` [m]: ``m``, ``cm`` (0.01), ``mm`` (0.001), ``um`` (1e-6), ``in`` (0.0254)
- ``"acceleration"`` [m/s²]: ``g`` (9.80665, standard gravity), ``m/s2``, ``cm/s2``
  (0.01), ``gal`` (0.01, the same size as cm/s2), ``mm/s2`` (0.001), ``in/s2`` (0.0254)
- ``"time"`` [s]: ``s``, ``ms`` (0.001), ``us`` (1e-6), ``min`` (60)
- ``"angle"`` [rad]: ``rad``, ``mrad`` (0.001), ``deg`` (pi/180)

Spellings are case-insensitive and blanks are ignored. Besides the canonical names a unit
may be written as a header writes it: ``m/s^2``, ``m/s**2``, ``m/s²``, ``m/s/s``,
``m/sec2``, ``m/sec^2``, ``m/sec/sec``, ``mps2`` (likewise for cm, mm and in), ``Gal`` /
``gals``, ``sec``, ``µs``, ``µm``, ``degree`` / ``degrees`` / ``°``, ``radian(s)``.

The public face is :data:`rockjax.UNITS` (a :class:`UnitTable`) and
:class:`rockjax.UnitError`::

    >>> import rockjax
    >>> rockjax.UNITS.to_si(250.0, "Gal", "acceleration")
    2.5
    >>> rockjax.UNITS.normalize("cm/s^2", "acceleration")
    'cm/s2'
    >>> rockjax.UNITS.split_token("Accel[gal]")
    ('Accel', 'gal')
    >>> dict(rockjax.UNITS["time"])
    {'s': 1.0, 'ms': 0.001, 'us': 1e-06, 'min': 60.0}
"""

from __future__ import annotations

import math
import re
import types
from collections.abc import Iterator, Mapping

__all__ = ["G_STANDARD", "UNITS", "UnitError", "UnitTable", "factor", "to_si"]

G_STANDARD = 9.80665
"""Standard gravity [m/s²], the size of the unit ``g``."""

_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "in": 0.0254}
_TABLE = {
    "length": _LENGTH,
    "acceleration": {
        "g": G_STANDARD,
        "m/s2": 1.0,
        "cm/s2": 1e-2,
        "gal": 1e-2,
        "mm/s2": 1e-3,
        "in/s2": 0.0254,
    },
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "angle": {"rad": 1.0, "mrad": 1e-3, "deg": math.pi / 180.0},
}
KINDS = tuple(_TABLE)
_SI = {"length": "m", "acceleration": "m/s2", "time": "s", "angle": "rad"}

# the ways a header spells "per second squared" after a length unit
_PER_S2 = ("/s2", "/s^2", "/s**2", "/s/s", "/sec2", "/sec^2", "/sec**2", "/sec/sec", "ps2")


def _spellings() -> dict[str, tuple[str, str]]:
    """spelling (lower case, no blanks) -> (kind, canonical name)."""
    out = {name: (kind, name) for kind, table in _TABLE.items() for name in table}
    for length in ("m", "cm", "mm", "in"):
        for tail in _PER_S2:
            out[length + tail] = ("acceleration", f"{length}/s2")
    out.update({
        "gals": ("acceleration", "gal"),
        "sec": ("time", "s"),
        "µs": ("time", "us"),  # micro sign
        "μs": ("time", "us"),  # Greek mu
        "µm": ("length", "um"),
        "μm": ("length", "um"),
        "degree": ("angle", "deg"),
        "degrees": ("angle", "deg"),
        "°": ("angle", "deg"),
        "radian": ("angle", "rad"),
        "radians": ("angle", "rad"),
    })
    return out


_SPELLINGS = _spellings()


def _key(unit) -> str:
    return str(unit).strip().lower().replace(" ", "").replace("²", "^2")


class UnitError(ValueError):
    """A unit that the table does not know (or of the wrong kind). The message names the
    unit and lists the known units of the kind asked for; ``unit``, ``kind`` and ``known``
    (the canonical names) are attributes."""

    def __init__(self, unit, kind: str | None = None, what: str | None = None):
        self.unit, self.kind = unit, kind
        every = tuple(n for t in _TABLE.values() for n in t)
        self.known = names(kind) if kind is not None else every
        found = kind_of(unit)
        subject = f"{what}: " if what else ""
        if kind is None:
            msg = f"{subject}unknown unit {unit!r}"
        elif found is not None:
            msg = f"{subject}{unit!r} is a unit of {found}, not of {kind}"
        else:
            msg = f"{subject}unknown unit {unit!r} of {kind}"
        known = ", ".join(self.known) if kind is not None else _listing()
        super().__init__(f"{msg}; known units{'' if kind is None else ' of ' + kind}: {known}")


def _listing() -> str:
    return "; ".join(f"{kind}: {', '.join(t)}" for kind, t in _TABLE.items())


def _check_kind(kind: str) -> None:
    if kind not in _TABLE:
        raise ValueError(f"unknown kind of unit {kind!r}; expected one of {', '.join(KINDS)}")


def names(kind: str) -> tuple[str, ...]:
    """The canonical names of the units of `kind`, SI first where it is listed first."""
    _check_kind(kind)
    return tuple(_TABLE[kind])


def kind_of(unit) -> str | None:
    """The kind (``"length"``, ``"acceleration"``, ``"time"``) of a spelling, or None
    when the table does not know it."""
    hit = _SPELLINGS.get(_key(unit))
    return None if hit is None else hit[0]


def normalize(unit, kind: str, what: str | None = None) -> str:
    """The canonical name of `unit` as a unit of `kind` (``"cm/s^2"`` -> ``"cm/s2"``,
    ``"Gal"`` -> ``"gal"``, ``"sec"`` -> ``"s"``); :class:`UnitError` otherwise (`what`,
    e.g. ``"units['u']"``, starts its message)."""
    _check_kind(kind)
    hit = _SPELLINGS.get(_key(unit))
    if hit is None or hit[0] != kind:
        raise UnitError(unit, kind, what)
    return hit[1]


def factor(unit, kind: str) -> float:
    """The size of `unit` (any spelling) in SI units of `kind`: ``factor("gal",
    "acceleration") == 0.01``; :class:`UnitError` for an unknown unit."""
    return _TABLE[kind][normalize(unit, kind)]


def to_si(value, unit, kind: str):
    """`value` (a number or a NumPy array) given in `unit`, in SI: ``value * factor(unit,
    kind)``."""
    return value * factor(unit, kind)


_BRACKET_RE = re.compile(r"(.*?)\s*[\[(]\s*([^\[\]()]*?)\s*[\])]\s*")


def split_token(token: str, kinds=None) -> tuple[str, str | None]:
    """(name, unit or None) of a header token: ``"u [mm]"``, ``"u (mm)"``, ``"Accel[gal]"``
    give the text in brackets (whatever it is: the caller checks it), ``"t_ms"``,
    ``"accel_cm/s2"`` an underscore suffix when it is a known unit (of one of `kinds`, a
    kind or a tuple of kinds, when given); the name is stripped, its case kept."""
    s = str(token).strip()
    m = _BRACKET_RE.fullmatch(s)
    if m:
        return m.group(1).strip(), m.group(2)
    base, sep, suffix = s.rpartition("_")
    if isinstance(kinds, str):
        kinds = (kinds,)
    found = kind_of(suffix)
    if sep and base and found is not None and (kinds is None or found in kinds):
        return base, suffix
    return s, None


class UnitTable(Mapping):
    """The unit table: a read-only mapping kind -> {canonical name: size in SI}, with the
    conversions as methods (see the module :mod:`rockjax._units` for the table).

    ``UNITS["acceleration"]["gal"] == 0.01``; ``UNITS.kinds``, ``UNITS.si`` (the SI unit
    of each kind), ``UNITS.spellings`` (every accepted spelling -> (kind, canonical name)).
    """

    kinds = KINDS
    si = types.MappingProxyType(dict(_SI))
    spellings = types.MappingProxyType(dict(_SPELLINGS))

    def __getitem__(self, kind: str) -> Mapping[str, float]:
        _check_kind(kind)
        return types.MappingProxyType(_TABLE[kind])

    def __iter__(self) -> Iterator[str]:
        return iter(_TABLE)

    def __len__(self) -> int:
        return len(_TABLE)

    def __repr__(self) -> str:
        return f"UnitTable({_listing()})"

    names = staticmethod(names)
    kind_of = staticmethod(kind_of)
    normalize = staticmethod(normalize)
    factor = staticmethod(factor)
    to_si = staticmethod(to_si)
    split_token = staticmethod(split_token)


UNITS = UnitTable()
"""The unit table of rockjax (see :class:`UnitTable`)."""
