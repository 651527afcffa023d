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

The files that rockjax does ship (the repository's ``data/`` folder, installed as the
package ``rockjax._data``: the Table 1 structure and the synthetic decay traces) are found
with `packaged_data_path`.
"""

from __future__ import annotations

import hashlib
import os
import pathlib
import shutil
import tempfile
import urllib.request

from rockjax._records import read_record, Record
from rockjax._structure import _data_file
from rockjax._textfile import normalize_rows, read_text

__all__ = [
    "EL_CENTRO_FILENAME",
    "EL_CENTRO_SHA256",
    "EL_CENTRO_URL",
    "cache_dir",
    "el_centro",
    "el_centro_path",
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
