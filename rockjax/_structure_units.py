"""Units of a structure file (`RockingStructure.from_toml` / `from_dict`), and the check
that its dimensions are plausible in SI.

A structure is always SI (kg, m, N/m, kg m², m/s²). A file may say otherwise:

- a ``units`` key names a **system**: ``"m"`` / ``"SI"`` / ``"N-m-kg"`` (SI, the
  default), ``"cm"``, ``"mm"`` or ``"in"`` (lengths in that unit, masses in kg, `k_f` in
  N per that unit, inertias in kg x that unit², `g` in that unit per s²), ``"N-mm-t"``
  (lengths mm, masses tonnes, forces N: `k_f` in N/mm, inertias t mm², `g` mm/s²) or
  ``"kN-m-t"`` (lengths m, masses tonnes, forces kN: `k_f` in kN/m, inertias t m²);
- a **suffix** on a field gives that field's own unit, whatever the system: lengths
  (``B_mm``, ``H_e_cm``, ``H_b_in``, ``B_m``), masses (``m_e_kg``, ``m_b_t``), the
  stiffness (``"k_f_N/m"``, ``"k_f_kN/m"``, ``"k_f_MN/m"``, ``"k_f_N/mm"``,
  ``"k_f_kN/mm"``), the inertias (``"I_eg_kg*m2"``, ``"I_eg_t*m2"``, ``"I_eg_kg*mm2"``,
  ``"I_eg_t*mm2"``) and `g` (any unit of acceleration of :data:`rockjax.UNITS`).

**Plausibility.** Dimensions that no rocking structure has in SI -- a half-width `B` over
100 m, a height `H_e` or `H_b` over 500 m (the McManus column of Table 1 written in mm is
B = 285, H_e = 1050) -- are refused with a hint on millimetres unless
``check_plausible=False``.
"""

from __future__ import annotations

import math

from . import _units
from ._errors import ParameterError

__all__ = ["SYSTEMS", "check_plausible", "to_si"]

_FIELDS = ("m_e", "m_b", "H_e", "H_b", "B", "I_eg", "I_bg", "k_f", "g")
_QUANTITY = {"m_e": "mass", "m_b": "mass", "H_e": "length", "H_b": "length",
             "B": "length", "I_eg": "inertia", "I_bg": "inertia", "k_f": "stiffness",
             "g": "acceleration"}

#: name -> (length [m], mass [kg], force [N]) of one unit of the system
SYSTEMS = {
    "m": (1.0, 1.0, 1.0), "si": (1.0, 1.0, 1.0), "n-m-kg": (1.0, 1.0, 1.0),
    "cm": (1e-2, 1.0, 1.0), "mm": (1e-3, 1.0, 1.0), "in": (0.0254, 1.0, 1.0),
    "n-mm-t": (1e-3, 1e3, 1.0), "kn-m-t": (1.0, 1e3, 1e3),
}
#: suffix -> size in SI, per quantity (lengths and accelerations: the unit table)
_SUFFIX = {
    "mass": {"kg": 1.0, "t": 1e3},
    "stiffness": {"n/m": 1.0, "kn/m": 1e3, "mn/m": 1e6, "n/mm": 1e3, "kn/mm": 1e6},
    "inertia": {"kg*m2": 1.0, "t*m2": 1e3, "kg*mm2": 1e-6, "t*mm2": 1e-3},
}
#: lengths over these [m] are implausible for a rocking structure
MAX_LENGTH = {"B": 100.0, "H_e": 500.0, "H_b": 500.0}


def _system_factors(name, source: str) -> dict[str, float]:
    key = str(name).strip().lower().replace(" ", "")
    if key not in SYSTEMS:
        raise ParameterError(f"{source}: unknown units {name!r} for a structure",
                             param="units", choices=("m", "mm", "cm", "in", "N-mm-t", "kN-m-t"))
    length, mass, force = SYSTEMS[key]
    return {"length": length, "mass": mass, "stiffness": force / length,
            "inertia": mass * length**2, "acceleration": length}


def _suffix_factor(field: str, suffix: str, source: str, key: str) -> float:
    quantity = _QUANTITY[field]
    s = suffix.strip().lower().replace(" ", "").replace("^", "").replace("²", "2")
    try:
        if quantity in ("length", "acceleration"):
            return _units.factor(s, quantity)
        return _SUFFIX[quantity][s.replace("·", "*")]
    except (_units.UnitError, KeyError):
        known = (", ".join(_units.names(quantity)) if quantity in ("length", "acceleration")
                 else ", ".join(_SUFFIX[quantity]))
        raise ValueError(f"{source}: {key}: unknown unit {suffix!r} of {quantity} for "
                         f"{field} (known: {known})") from None


def _split_key(key: str) -> tuple[str, str | None] | None:
    """(field, suffix or None) of a key, or None for a key that names no field."""
    if key in _FIELDS:
        return key, None
    for field in sorted(_FIELDS, key=len, reverse=True):
        if key.startswith(field + "_") and len(key) > len(field) + 1:
            return field, key[len(field) + 1:]
    return None


def to_si(d: dict, source: str) -> dict[str, float]:
    """The fields of the table `d` in SI (floats); ValueError naming the key for an unknown
    key, a missing field, a field given twice or a value that is not a number."""
    factors = _system_factors(d.get("units", "m"), source)
    values: dict[str, float] = {}
    keys: dict[str, str] = {}
    unknown = []
    for key, v in d.items():
        if key == "units":
            continue
        split = _split_key(key)
        if split is None:
            unknown.append(key)
            continue
        field, suffix = split
        if field in keys:
            raise ValueError(f"{source}: {field} given twice ({keys[field]} and {key})")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"{source}: parameter {key} must be a number, got {v!r}")
        size = (factors[_QUANTITY[field]] if suffix is None
                else _suffix_factor(field, suffix, source, key))
        values[field], keys[field] = float(v) * size, key
    if unknown:
        raise ValueError(f"{source}: unknown parameter(s) {', '.join(sorted(unknown))}")
    missing = [k for k in _FIELDS[:-1] if k not in values]
    if missing:
        raise ValueError(f"{source}: missing parameter(s) {', '.join(missing)}")
    return values


def check_plausible(values: dict[str, float], d: dict, source: str) -> None:
    """ParameterError (param ``check_plausible``) for a length implausible in SI, with a
    hint on millimetres."""
    for field, limit in MAX_LENGTH.items():
        x = values[field]
        if not (math.isfinite(x) and x > limit):
            continue
        stated = "" if "units" not in d else f" with units = {d['units']!r}"
        raise ParameterError(
            f"{source}: {field} = {x:g} m{stated} is implausible for a rocking structure "
            f"(more than {limit:g} m); if the file is in millimetres, add units = \"mm\" "
            f"(or \"N-mm-t\") at its top or write {field}_mm = {x:g}; or read it as it is",
            param="check_plausible", choices=(False,))
