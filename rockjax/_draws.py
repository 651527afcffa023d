"""Posterior draws of a structure's parameters: `rockjax.read_draws` and the checks and
per-draw structures of the posterior-predictive curves (`_predictive.py`).

Draws travel from a fit (the `identification` package, which rockjax does not import) to
the predictions as a plain mapping name -> 1-D array of physical SI values, one entry per
draw, e.g. ``{"k_f": (200,), "r": (200,)}``; on disk as a CSV (`read_draws`): a first
line ``# units: k_f N/m, r -``, a header of the plain names, one row per draw.

The names: any field of `rockjax.RockingStructure` (`FIELDS`), `r` (the coefficient of
restitution, in place of Eq. 3's) and `c_f` (the 2-DOF body's dashpots, the `damping` of
`rockjax.TwoSpring2DOF`). A fit's nuisance parameters (`NUISANCE`: the release state and
the sensors' zeros), which do not enter a prediction, are left out by `read_draws` and
listed in its `ignored` output; any other name is an error naming the column.
"""

from __future__ import annotations

import csv
import math
import pathlib
import re

import numpy as np

from ._errors import ParameterError
from ._structure import FIELDS, RockingStructure

#: the SI unit of every parameter a draw may set
SI_UNITS = {"m_e": "kg", "m_b": "kg", "H_e": "m", "H_b": "m", "B": "m", "I_eg": "kg m2",
            "I_bg": "kg m2", "k_f": "N/m", "g": "m/s2", "r": "-", "c_f": "N s/m"}
#: the names a draw may set: the structure's fields, r and c_f
PARAMETERS = tuple(SI_UNITS)
#: identification's nuisance parameters (release state, sensor zeros and drift, the clock
#: offset of a shake-table run): in a draws file, read and left out (they do not enter a
#: prediction), also with a run's index (`u0[2]`, a joint fit's)
NUISANCE = ("u0", "t0", "offset", "offset_uplift", "offset_theta", "drift", "clock_offset")
#: the fewest draws of a band
MIN_DRAWS = 2
#: spellings of "dimensionless"
_NONE_UNITS = ("-", "", "1", "none")


def _unit_key(text):
    """A unit spelled plainly: no spaces, `*`, `·` or `^`; ² as 2; lower case."""
    t = text.strip().replace("²", "2").replace("·", "").replace("*", "").replace("^", "")
    return re.sub(r"\s+", "", t).lower()


def _unit_ok(name, unit):
    want = SI_UNITS[name]
    if want == "-":
        return _unit_key(unit) in _NONE_UNITS
    return _unit_key(unit) == _unit_key(want)


def _parse_units(line, where):
    """{name: unit} of a `# units: k_f N/m, r -` line."""
    body = line.split(":", 1)[1]
    out = {}
    for item in body.split(","):
        item = item.strip()
        if not item:
            continue
        name, _, unit = item.partition(" ")
        if name in out:
            raise ParameterError(f"{where}: the units line names {name} twice", param="draws")
        out[name] = unit.strip()
    return out


def _read_rows(path):
    """(units {name: unit} or None, header, rows as (line number, cells))."""
    units, header, rows = None, None, []
    with open(path, newline="", encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                if header is None and re.match(r"#\s*units\s*:", text, re.I):
                    units = _parse_units(text, f"{path}, line {lineno}")
                continue
            cells = next(csv.reader([text]))
            if header is None:
                header = [c.strip() for c in cells]
            else:
                rows.append((lineno, [c.strip() for c in cells]))
    if header is None:
        raise ParameterError(f"{path}: no header line (the parameter names, e.g. k_f,r)",
                             param="draws")
    return units, header, rows


def _check_columns(path, units, header, ignore):
    """The columns taken and those left out (in `ignore`); errors name the column."""
    seen = set()
    for name in header:
        if not name:
            raise ParameterError(f"{path}: an empty column name in the header", param="draws")
        if name in seen:
            raise ParameterError(f"{path}: column {name} appears twice", param="draws")
        seen.add(name)
    unknown = [n for n in header if n not in PARAMETERS and not _ignored(n, ignore)]
    if unknown:
        raise ParameterError(
            f"{path}: column {unknown[0]} is not a parameter of a prediction (known: "
            f"{', '.join(PARAMETERS)}; left out: {', '.join(ignore) or 'none'}); pass "
            f"ignore=[...] (--draws-ignore) to leave it out", param="draws")
    if units is not None:
        extra = [n for n in units if n not in header]
        if extra:
            raise ParameterError(f"{path}: the units line names {extra[0]}, which is not a "
                                 "column", param="draws")
        for name in header:
            if _ignored(name, ignore):
                continue
            if name not in units:
                raise ParameterError(f"{path}: the units line gives no unit for column {name} "
                                     f"(SI: {SI_UNITS[name]})", param="draws")
            if not _unit_ok(name, units[name]):
                raise ParameterError(
                    f"{path}: column {name} is in {units[name]!r}, not its SI unit "
                    f"{SI_UNITS[name]!r}: draws are read in SI units; convert them",
                    param="draws")
    return [n for n in header if n in PARAMETERS], [n for n in header if _ignored(n, ignore)]


def _ignored(name, ignore):
    """Whether column `name` is left out: in `ignore`, or `x[i]` with x in `ignore`."""
    return name in ignore or re.sub(r"\[\d+\]$", "", name) in ignore


def read_draws(path, *, ignore=NUISANCE) -> dict:
    r"""Posterior draws from a CSV file: name -> 1-D array of SI values, one per draw.

    The file (as `identification.Posterior.to_csv` writes it): an optional first line
    ``# units: k_f N/m, r -, ...`` (each column's unit, which must be its SI unit: N/m,
    N s/m, kg, m, kg m2, m/s2, or ``-`` for r; other comment lines are skipped), a header
    of plain names, then one row of numbers per draw.

    **Arguments:** `path`; `ignore`: columns to read and leave out (default `NUISANCE`, a
    fit's release state, sensor zeros and clock offset, which do not enter a prediction;
    a name also covers its indexed columns, `u0[0]`, `u0[1]`, ... of a joint fit).

    **Returns:** a dict of the columns that a prediction uses (the fields of
    `rockjax.RockingStructure`, `r`, `c_f`), each a float array of the same length.

    **Errors** (`ParameterError`, naming the column or the row): a column that is none of
    these nor ignored; a unit that is not the column's SI unit, or missing from a units
    line; a row of another length; a cell that is not a finite number; fewer than 2
    draws; no column to use.

    **Example:** `rockjax.read_draws("draws.csv")` -> ``{"k_f": array([...]), "r":
    array([...])}``.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"draws file not found: {path}")
    ignore = tuple(ignore or ())
    units, header, rows = _read_rows(path)
    taken, _ = _check_columns(path, units, header, ignore)
    if not taken:
        raise ParameterError(f"{path}: no column to predict with (the columns are "
                             f"{', '.join(header)}; known: {', '.join(PARAMETERS)})",
                             param="draws")
    cols = {n: [] for n in taken}
    for lineno, cells in rows:
        if len(cells) != len(header):
            raise ParameterError(f"{path}, line {lineno}: {len(cells)} values for the "
                                 f"{len(header)} columns of the header", param="draws")
        for name, cell in zip(header, cells):
            if name not in cols:
                continue
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise ParameterError(f"{path}, line {lineno}: column {name} is {cell!r}, not "
                                     "a finite number", param="draws")
            cols[name].append(v)
    if len(rows) < MIN_DRAWS:
        raise ParameterError(f"{path}: {len(rows)} draw(s); a band needs at least "
                             f"{MIN_DRAWS}", param="draws")
    return {n: np.asarray(v, float) for n, v in cols.items()}


def check_draws(draws, ignore=NUISANCE) -> dict:
    """The draws as a dict of float arrays of one length >= 2 (`MIN_DRAWS`): known names
    (`PARAMETERS`), finite values, r in [0, 1], c_f >= 0; errors name the parameter and
    the draw. The names in `ignore` (default `NUISANCE`, as `read_draws`: a fit's release
    state, sensor zeros and clock offset, which `identification.Posterior.draws_dict()`
    gives beside k_f and r) are left out."""
    if not hasattr(draws, "items"):
        raise ParameterError(f"draws must be a mapping name -> 1-D array (e.g. from "
                             f"rockjax.read_draws), got {type(draws).__name__}", param="draws")
    out = {}
    for name, v in draws.items():
        if _ignored(name, tuple(ignore or ())):
            continue
        if name not in PARAMETERS:
            raise ParameterError(f"draws: {name!r} is not a parameter of a prediction (known: "
                                 f"{', '.join(PARAMETERS)})", param="draws")
        a = np.asarray(v, float)
        if a.ndim != 1:
            raise ParameterError(f"draws: {name} must be a 1-D array (one value per draw), got "
                                 f"shape {a.shape}", param="draws")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ParameterError(f"draws: {name} of draw {bad[0]} is {a[bad[0]]}, not finite",
                                 param="draws")
        out[name] = a
    if not out:
        raise ParameterError("draws: empty (no parameter)", param="draws")
    sizes = {n: a.size for n, a in out.items()}
    if len(set(sizes.values())) > 1:
        raise ParameterError(f"draws: the parameters have different numbers of draws ({sizes})",
                             param="draws")
    n = next(iter(sizes.values()))
    if n < MIN_DRAWS:
        raise ParameterError(f"draws: {n} draw(s); a band needs at least {MIN_DRAWS}",
                             param="draws")
    for name, lo, hi in (("r", 0.0, 1.0), ("c_f", 0.0, np.inf)):
        if name in out:
            bad = np.flatnonzero((out[name] < lo) | (out[name] > hi))
            if bad.size:
                raise ParameterError(f"draws: {name} of draw {bad[0]} is {out[name][bad[0]]}, "
                                     f"outside [{lo:g}, {hi:g}]", param="draws")
    return out


def n_draws(draws) -> int:
    return next(iter(draws.values())).size


def draw_structures(structure, draws) -> RockingStructure:
    """The structure with each drawn field an array (n_draws,) (the others as given); an
    unphysical draw is an error naming it (its index and the parameter)."""
    fields = {f: draws[f] for f in FIELDS if f in draws}
    if not fields:
        return structure
    try:
        return structure.replace(**fields)
    except ValueError:
        for i in range(n_draws(draws)):
            try:
                structure.replace(**{f: v[i] for f, v in fields.items()})
            except ValueError as e:
                values = ", ".join(f"{f} = {v[i]:.6g}" for f, v in fields.items())
                raise ParameterError(f"draws: draw {i} ({values}): {e}", param="draws") from None
        raise


def member_structure(structure, index):
    """The structure of members `index` (draw indices) from `draw_structures`' output:
    each (n_draws,) field taken at `index`, scalar fields kept."""
    return RockingStructure(**{f: (np.asarray(getattr(structure, f))[index]
                                   if np.ndim(getattr(structure, f)) == 1
                                   else getattr(structure, f)) for f in FIELDS})


def describe(draws) -> list[dict]:
    """Per parameter: name, SI unit, median and the 5 and 95 % quantiles over the draws."""
    out = []
    for name, a in draws.items():
        q = np.quantile(a, [0.05, 0.5, 0.95])
        out.append({"name": name, "unit": SI_UNITS[name], "median": float(q[1]),
                    "q05": float(q[0]), "q95": float(q[2])})
    return out
