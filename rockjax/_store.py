"""The store of a sweep: labelled arrays on disk, written chunk by chunk as the runs go.

A Zarr (format 3) group that xarray opens (`xarray.open_zarr(path)`): the per-run
summaries `VARIABLES` on the dimensions (structure, record, scale), each with its units,
the coordinates (structure and record labels, the scale factors), per-record provenance
on the record dimension, a `done` mask on (structure, scale), and the sweep's parameters
and provenance as attributes (JSON). Zarr, not netCDF: every chunk of every variable is
its own file, written once, so a sweep writes its chunks as they finish without touching
the rest, several processes write theirs side by side, and a rerun finds the chunks done
in the `done` mask and skips them (`rockjax.sweep_store`, in `_sweep`, runs the chunks).

Zarr and xarray are optional (`pip install "rockjax[store]"`); nothing here is imported
until a store is asked for.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import pathlib
import warnings

import numpy as np

from ._errors import ParameterError
from ._status import STATUS

#: the value of the attribute `rockjax_store` of a finished store (another is refused)
STORE_FORMAT = "rockjax sweep store, format 1"
#: the attribute `rockjax_store` while the store is being created (a rerun recreates it)
_CREATING = "rockjax sweep store, being created"
#: the dimensions of the per-run variables
DIMS = ("structure", "record", "scale")
#: the per-run variables: (dtype, fill value of a run not yet written, attributes)
VARIABLES = {
    "peak_u": ("float64", np.nan, {
        "units": "m", "long_name": "peak |u| of the run (uplift displacement of the "
        "centre, continuous solution)"}),
    "peak_uplift": ("float64", np.nan, {"units": "m", "long_name": "peak corner uplift"}),
    "n_impacts": ("int32", -1, {"units": "1", "long_name": "impacts counted"}),
    "status": ("int8", -1, {
        "long_name": "how the run ended (-1: not run yet)",
        "flag_values": sorted(STATUS.values()),
        "flag_meanings": " ".join(sorted(STATUS, key=STATUS.get))}),
    "t_overturn": ("float64", np.nan, {
        "units": "s", "long_name": "time of overturning (inf: did not overturn)"}),
    "t_end": ("float64", np.nan, {
        "units": "s", "long_name": "end of the run: its record's end + tail, at most t1"}),
}
#: runs per chunk by default: one compiled call of 4,096 runs per device on two devices
DEFAULT_CHUNK_RUNS = 8192
_INSTALL = 'pip install "rockjax[store]" (zarr and xarray)'


def _zarr():
    try:
        import zarr
    except ImportError:  # pragma: no cover - the optional extra not installed
        raise ImportError(f"a sweep's store needs zarr: {_INSTALL}") from None
    return zarr


def open_dataset(path):
    """The store at `path` as an `xarray.Dataset` (lazy: nothing read until used)."""
    try:
        import xarray
    except ImportError:  # pragma: no cover - the optional extra not installed
        raise ImportError(f"reading a sweep's store needs xarray: {_INSTALL}") from None
    return xarray.open_zarr(str(path), consolidated=False, chunks=None)


def jsonable(x):
    """`x` as plain JSON values (numpy scalars and arrays as numbers and lists, anything
    else that JSON cannot hold as its repr), the form the store's attributes keep."""
    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        return repr(o)

    return json.loads(json.dumps(x, default=default))


def array_sha256(*arrays) -> str:
    """The SHA-256 of arrays as float64 bytes (a record's samples and dt, the scales)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, np.float64).tobytes())
    return h.hexdigest()


def scale_chunk(n_records, n_scales, chunk_runs):
    """Scales per chunk: about `chunk_runs` runs of one structure, every record in each
    chunk, the scales split into chunks of equal size."""
    if not (isinstance(chunk_runs, (int, np.integer)) and chunk_runs >= 1):
        raise ParameterError(f"chunk_runs must be a positive integer, got {chunk_runs!r}",
                             param="chunk_runs")
    per = max(1, int(chunk_runs) // n_records)
    return math.ceil(n_scales / math.ceil(n_scales / per))


@dataclasses.dataclass
class SweepStore:
    """An open store: `group` (zarr), its shape and the scales per chunk."""

    path: pathlib.Path
    group: object
    n_structures: int
    n_records: int
    n_scales: int
    chunk: int

    @property
    def n_chunks(self) -> int:
        """Chunks per structure (along the scales)."""
        return math.ceil(self.n_scales / self.chunk)

    def scales_of(self, c):
        """[lo, hi) of the scales of chunk `c`."""
        return c * self.chunk, min(self.n_scales, (c + 1) * self.chunk)

    @classmethod
    def open(cls, path, coords=None, parameters=None, provenance=None, chunk=None,
             create=True):
        """The store at `path`: created when absent (or left half-created), else opened
        and its parameters checked against `parameters` (a `ParameterError` naming the
        first that differs; None: no check). `coords`: structure and record labels,
        scales, and per-record variables; `create=False`: open only (another process
        creates it)."""
        zarr, path = _zarr(), pathlib.Path(path)
        attrs = _attributes(path)
        if attrs is None or attrs.get("rockjax_store") == _CREATING:
            if not create:
                raise ParameterError(f"no sweep store at {path}", param="store")
            if attrs is None and path.exists() and any(path.iterdir()):
                raise ParameterError(f"{path} exists and is not a rockjax sweep store; give "
                                     "a new path or remove it", param="store")
            _create(zarr, path, coords, parameters, provenance, chunk)
        elif attrs.get("rockjax_store") != STORE_FORMAT:
            raise ParameterError(f"{path} is not a rockjax sweep store of this version "
                                 f"({attrs.get('rockjax_store')!r}); give a new path",
                                 param="store")
        elif parameters is not None:
            check_parameters(path, attrs.get("parameters", {}), parameters)
        group = zarr.open_group(str(path), mode="r+")
        _, n_r, n_s = group["peak_u"].shape
        return cls(path, group, group["peak_u"].shape[0], n_r, n_s, group["done"].chunks[1])

    def done(self):
        """The `done` mask, (n_structures, n_scales) booleans."""
        return np.asarray(self.group["done"][...], bool)

    def pending(self):
        """[(structure, chunk)] of the chunks not yet written, structure-major."""
        done = self.done()
        return [(s, c) for s in range(self.n_structures) for c in range(self.n_chunks)
                if not done[s, slice(*self.scales_of(c))].all()]

    def write(self, s, c, fields):
        """Chunk `c` of structure `s`: each of `VARIABLES` (n_records, its scales), then
        its part of the `done` mask (a chunk killed mid-write is not marked done)."""
        lo, hi = self.scales_of(c)
        for name, (dtype, _, _) in VARIABLES.items():
            self.group[name][s, :, lo:hi] = np.asarray(fields[name]).astype(dtype)
        self.group["done"][s, lo:hi] = True


def _attributes(path):
    """The attributes of the Zarr group at `path`, or None when there is none."""
    meta = pathlib.Path(path) / "zarr.json"
    if not meta.is_file():
        return None
    try:
        return json.loads(meta.read_text()).get("attributes", {})
    except (OSError, ValueError):
        return None


def _create(zarr, path, coords, parameters, provenance, chunk):
    """A new store: marked as being created, the arrays, the coordinates, and the
    attributes last (a store killed while created is recreated by the next run)."""
    labels_s, labels_r, scales = coords["structure"], coords["record"], coords["scale"]
    shape = (len(labels_s), len(labels_r), len(scales))
    group = zarr.open_group(str(path), mode="w", zarr_format=3,
                            attributes={"rockjax_store": _CREATING})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zarr: fixed-length strings "not yet stable"
        extra = {"coordinates": " ".join(coords.get("per_record", {}))}
        for name, (dtype, fill, attrs) in VARIABLES.items():
            attrs = {**attrs, **extra} if extra["coordinates"] else attrs
            group.create_array(name, shape=shape, chunks=(1, shape[1], chunk), dtype=dtype,
                               fill_value=fill, dimension_names=DIMS, attributes=attrs)
        group.create_array("done", shape=(shape[0], shape[2]), chunks=(1, chunk),
                           dtype="bool", fill_value=False,
                           dimension_names=("structure", "scale"),
                           attributes={"long_name": "the runs of this structure and scale "
                                       "are written"})
        for name, values, dim, attrs in _coordinates(coords):
            values = np.asarray(values)
            arr = group.create_array(name, shape=values.shape, chunks=values.shape or None,
                                     dtype=str if values.dtype.kind == "U" else values.dtype,
                                     dimension_names=(dim,), attributes=attrs)
            arr[...] = values
    group.update_attributes({"rockjax_store": STORE_FORMAT, **provenance,
                             "parameters": parameters})


def _coordinates(coords):
    """(name, values, dimension, attributes) of the coordinate and per-record arrays."""
    out = [("structure", coords["structure"], "structure", {"long_name": "structure label"}),
           ("record", coords["record"], "record", {"long_name": "record label"}),
           ("scale", np.asarray(coords["scale"], float), "scale",
            {"units": "1", "long_name": "scale factor on the record's acceleration"})]
    for name, (values, attrs) in coords.get("per_record", {}).items():
        out.append((name, values, "record", attrs))
    return out


def check_parameters(path, stored, given):
    """Refuse a rerun into `path` whose parameters differ from the stored ones: a
    `ParameterError` naming the first parameter that differs (and where inside it)."""
    for key in dict.fromkeys([*stored, *given]):
        old, new = stored.get(key), given.get(key)
        if old != new:
            where, old, new = _difference(key, old, new)
            raise ParameterError(
                f"the store {path} holds a sweep whose {where} differs: {_brief(old)} there, "
                f"{_brief(new)} here; rerun with the same arguments to resume it, or give a "
                "new store path", param=key)


def _difference(where, old, new):
    """(where, old, new) of the first difference inside two JSON values."""
    if isinstance(old, dict) and isinstance(new, dict) and old.keys() == new.keys():
        if {"n", "first", "last"} <= old.keys():  # the scales: their count and ends
            if (old["n"], old["first"], old["last"]) != (new["n"], new["first"], new["last"]):
                return where, *(f"{d['n']} from {d['first']:g} to {d['last']:g}"
                                for d in (old, new))
            return where, "values", "other values of the same count and ends"
        k = next(k for k in old if old[k] != new[k])
        return _difference(f"{where}[{k!r}]" if where == "structure" else f"{where} {k}",
                           old[k], new[k])
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        i = next(i for i, (a, b) in enumerate(zip(old, new)) if a != b)
        label = old[i].get("label", i) if isinstance(old[i], dict) else i
        return _difference(f"{where} [{label!r}]", old[i], new[i])
    return where, old, new


def _brief(value, width=60):
    """A value of the parameters, as short text."""
    if value is None:
        return "not given"
    text = value if isinstance(value, str) else json.dumps(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def runs_done(path) -> int:
    """The runs already written into the store at `path` (0 when there is none)."""
    attrs = _attributes(path)
    if attrs is None or attrs.get("rockjax_store") != STORE_FORMAT:
        return 0
    group = _zarr().open_group(str(path), mode="r")
    return int(np.asarray(group["done"][...]).sum()) * group["peak_u"].shape[1]
