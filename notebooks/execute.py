"""Execute the notebooks in place, with their figures, and stamp them with their inputs.

    python notebooks/execute.py                        # every notebooks/*.ipynb
    python notebooks/execute.py notebooks/03_earthquake.ipynb
    python notebooks/execute.py --check                # only report stale stamps (exit 1)

Each notebook runs top to bottom in a fresh `python3` kernel (nbclient), in a temporary
working folder, with the environment of `tests/test_notebooks.py`: `ROCKJAX_EL_CENTRO`
names the shared El Centro record (`../shared/data/ground_motions/IELC180.AT2` beside the
checkout, or `$ROCKJAX_SHARED_DATA/IELC180.AT2`) and `ROCKJAX_CACHE` a temporary folder, so
nothing is downloaded. Committed outputs must show the real record: without it the script
refuses to run a notebook that reads El Centro, unless `--allow-fallback` is given (the
notebook then shows its labelled synthetic stand-in and is stamped `"el_centro":
"fallback"`, which the tests reject).

Outputs are kept small and deterministic: figures are inline PNGs at `--dpi` (72 by
default, set on the kernel's command line so that no code cell changes), written without
matplotlib's version string; execution timestamps and widget state are not recorded; the
JSON is written by nbformat (sorted keys). A notebook over `MAX_BYTES` is reported and the
script exits 1.

The freshness stamp, `nb.metadata["rockjax"]`, holds `version` (rockjax's `__version__`)
and `inputs_sha256`, a hash of everything that decides the outputs and lives in the
repository (see `inputs_sha256`). `tests/test_notebooks.py` recomputes it from the current
sources, so a change to a notebook's code or to the package makes the test name the
notebooks to run again.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import os
import pathlib
import re
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = REPO / "notebooks"
#: the folders whose every `*.py` decides what the notebooks print and draw
PACKAGES = ("rockjax", "identification")
#: the package data shipped as `rockjax._data` (the Table 1 column, the synthetic traces)
PACKAGE_DATA = ("data/*.toml", "data/*.csv", "data/*.json")
MAX_BYTES = 300_000
DPI = 80
TIMEOUT = 900  # seconds per cell
FALLBACK = "El Centro unavailable"  # what each notebook prints when it falls back
EL_CENTRO_FILE = "IELC180.AT2"
STAMP_FORMAT = 1  # bump when the hash below changes its definition


# --------------------------------------------------------------------------- the stamp


def _normalised(data: bytes) -> bytes:
    return data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")


def input_files(repo: pathlib.Path = REPO) -> list[pathlib.Path]:
    """The package's source and data files, sorted by their path relative to `repo`."""
    files = {p for pkg in PACKAGES for p in (repo / pkg).rglob("*.py")}
    files |= {p for pattern in PACKAGE_DATA for p in repo.glob(pattern)}
    files = {p for p in files if p.is_file() and "__pycache__" not in p.parts}
    return sorted(files, key=lambda p: p.relative_to(repo).as_posix())


def rockjax_version(repo: pathlib.Path = REPO) -> str:
    """`rockjax.__version__`, read from the checkout's source (no import, no JAX)."""
    text = (repo / "rockjax" / "__init__.py").read_text(encoding="utf-8")
    match = re.search(r"""^__version__\s*=\s*["']([^"']+)["']""", text, re.MULTILINE)
    if match is None:
        raise RuntimeError("no __version__ in rockjax/__init__.py")
    return match.group(1)


def code_sources(nb) -> list[str]:
    """The sources of a notebook's code cells, in order."""
    return [
        "".join(c["source"]) if isinstance(c["source"], list) else c["source"]
        for c in nb["cells"]
        if c["cell_type"] == "code"
    ]


def inputs_sha256(nb, repo: pathlib.Path = REPO, version: str | None = None) -> str:
    """SHA-256 of the inputs that decide a notebook's outputs.

    Hashed, each as a length-prefixed field so that no two different inputs run together
    the same way: the stamp format, rockjax's version, every code cell's source (in order;
    markdown and outputs are not inputs), then the path (relative to `repo`, `/`-separated)
    and bytes of every `*.py` under rockjax/ and identification/ and of the package data
    (`PACKAGE_DATA`), sorted by path. Line endings are normalised to `\\n`, so a checkout
    with CRLF endings gives the same hash. The shared El Centro record is outside the
    repository: whether it was used is recorded beside the stamp, not hashed.
    """
    h = hashlib.sha256()

    def field(data: bytes) -> None:
        h.update(len(data).to_bytes(8, "big"))
        h.update(data)

    field(f"rockjax-notebook-inputs {STAMP_FORMAT}".encode())
    field((version if version is not None else rockjax_version(repo)).encode())
    sources = code_sources(nb)
    field(str(len(sources)).encode())
    for source in sources:
        field(_normalised(source.encode("utf-8")))
    for path in input_files(repo):
        field(path.relative_to(repo).as_posix().encode("utf-8"))
        field(_normalised(path.read_bytes()))
    return h.hexdigest()


def stamp(nb, repo: pathlib.Path = REPO) -> dict:
    """The freshness stamp of `nb` from the current sources: {version, inputs_sha256}."""
    version = rockjax_version(repo)
    return {"version": version, "inputs_sha256": inputs_sha256(nb, repo, version)}


def is_fresh(nb, repo: pathlib.Path = REPO) -> bool:
    """Whether `nb`'s recorded stamp matches its current inputs."""
    recorded = nb.get("metadata", {}).get("rockjax", {})
    return {k: recorded.get(k) for k in ("version", "inputs_sha256")} == stamp(nb, repo)


# --------------------------------------------------------------------------- execution


def shared_el_centro() -> pathlib.Path:
    """The shared El Centro record, as `tests/conftest.py` finds it (it may be absent)."""
    env = os.environ.get("ROCKJAX_SHARED_DATA")
    folder = pathlib.Path(env) if env else REPO.parent / "shared" / "data" / "ground_motions"
    return folder / EL_CENTRO_FILE


def uses_el_centro(nb) -> bool:
    """Whether `nb` reads the shared records: El Centro, or the shared folder."""
    return any("datasets.el_centro()" in s or "ROCKJAX_SHARED_DATA" in s
               for s in code_sources(nb))


def kernel_arguments(dpi: int | None = DPI) -> list[str]:
    """IPython options on the kernel's command line: inline PNGs at `dpi`, tight boxes,
    without matplotlib's version string (so a new matplotlib does not change every PNG)."""
    kwargs = {"bbox_inches": "tight", "metadata": {"Software": None}}
    if dpi is not None:
        kwargs["dpi"] = dpi
    return ["--InlineBackend.figure_formats={'png'}",
            f"--InlineBackend.print_figure_kwargs={kwargs!r}"]


def execute_notebook(nb, *, el_centro: pathlib.Path, workdir: pathlib.Path,
                     dpi: int | None = DPI, timeout: int = TIMEOUT):
    """Run `nb` (a NotebookNode, changed in place) in a fresh `python3` kernel.

    The kernel's environment is this process's plus `ROCKJAX_EL_CENTRO=el_centro` (a
    missing file makes the notebooks fall back to synthetic motion), `ROCKJAX_SHARED_DATA`
    its folder (the shared records of notebooks 08 and 09), `ROCKJAX_SHAKEBOT` the shared
    ShakeBot table beside it (notebook 09) and `ROCKJAX_CACHE`
    under `workdir`, the kernel's working folder. Raises nbclient's CellExecutionError.
    """
    import nbclient

    env = dict(os.environ, ROCKJAX_EL_CENTRO=str(el_centro),
               ROCKJAX_SHARED_DATA=str(pathlib.Path(el_centro).parent),
               ROCKJAX_SHAKEBOT=str(pathlib.Path(el_centro).parent.parent / "shakebot"
                                    / "exp270.csv"),
               ROCKJAX_CACHE=str(pathlib.Path(workdir) / "cache"))
    client = nbclient.NotebookClient(
        nb, timeout=timeout, kernel_name="python3", record_timing=False,
        extra_arguments=kernel_arguments(dpi),
        resources={"metadata": {"path": str(workdir)}},
    )
    client.execute(env=env)
    return nb


def outputs(nb, output_type: str) -> list:
    return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
            if o.get("output_type") == output_type]


def printed(nb) -> str:
    return "".join(o.get("text", "") for o in outputs(nb, "stream"))


def shrink_png(data: str) -> str:
    """A base64 PNG re-encoded with a 256-colour palette where that is smaller.

    Matplotlib's line plots hold a few thousand colours, nearly all antialiasing shades of
    the few line colours; a palette of 256 (Pillow's fast octree, deterministic) draws them
    indistinguishably at about a third of the bytes. Images with transparency are left as
    they are.
    """
    import base64
    import io

    from PIL import Image

    raw = base64.b64decode(data)
    image = Image.open(io.BytesIO(raw))
    if image.mode == "RGBA" and image.getextrema()[3][0] < 255:
        return data
    buffer = io.BytesIO()
    image.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE).save(
        buffer, format="png", optimize=True)
    small = buffer.getvalue()
    return base64.b64encode(small).decode("ascii") + "\n" if len(small) < len(raw) else data


def shrink_images(nb) -> None:
    """`shrink_png` on every PNG output of `nb`."""
    for output in outputs(nb, "display_data") + outputs(nb, "execute_result"):
        data = output.get("data", {})
        if "image/png" in data:
            data["image/png"] = shrink_png(data["image/png"])


def strip_volatile(nb) -> None:
    """Drop what changes from run to run without changing the content."""
    nb.metadata.pop("widgets", None)
    nb.metadata.pop("papermill", None)
    for cell in nb.cells:
        for key in ("execution", "ExecuteTime", "papermill"):
            cell.metadata.pop(key, None)


def _check_kernel_imports_this_checkout() -> None:
    import importlib.util

    spec = importlib.util.find_spec("rockjax")
    here = (REPO / "rockjax" / "__init__.py").resolve()
    if spec is None or spec.origin is None or pathlib.Path(spec.origin).resolve() != here:
        found = None if spec is None else spec.origin
        sys.exit(f"this Python imports rockjax from {found}, not from {here}: install the "
                 "checkout (pip install -e '.[dev]') and run the script with its Python")


def refresh(path: pathlib.Path, *, allow_fallback: bool = False, dpi: int | None = DPI,
            shrink: bool = True, timeout: int = TIMEOUT) -> tuple[bool, str]:
    """Execute one notebook, stamp it and write it back. Returns (ok, message)."""
    import nbclient
    import nbformat

    nb = nbformat.read(path, as_version=4)
    record = shared_el_centro()
    reads_record = uses_el_centro(nb)
    if reads_record and not record.is_file() and not allow_fallback:
        return False, (f"refused: it reads El Centro and {record} is missing (committed "
                       "outputs must show the real record; --allow-fallback to run anyway)")
    fresh_stamp = stamp(nb)  # from the sources that are about to run
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    with tempfile.TemporaryDirectory(prefix="rockjax-notebook-") as work:
        if not record.is_file():
            record = pathlib.Path(work) / "no-el-centro" / EL_CENTRO_FILE
        try:
            execute_notebook(nb, el_centro=record, workdir=pathlib.Path(work), dpi=dpi,
                             timeout=timeout)
        except nbclient.exceptions.CellExecutionError as exc:
            return False, f"failed, not written:\n{str(exc)[-3000:]}"
        except (nbclient.exceptions.DeadKernelError, TimeoutError) as exc:
            return False, f"failed, not written: {type(exc).__name__}: {exc}"
    fell_back = FALLBACK in printed(nb)
    if fell_back and not allow_fallback:
        return False, f"printed {FALLBACK!r}, not written (--allow-fallback to keep it)"
    strip_volatile(nb)
    if shrink:
        shrink_images(nb)
    nb.metadata["rockjax"] = {
        **fresh_stamp,
        "executed": datetime.date.today().isoformat(),
        **({"el_centro": "fallback" if fell_back else "real"} if reads_record else {}),
    }
    nbformat.validate(nb)
    nbformat.write(nb, path)
    size = path.stat().st_size
    if size > MAX_BYTES:
        return False, f"written, but {size / 1e3:.0f} kB > {MAX_BYTES / 1e3:.0f} kB: lower --dpi"
    return True, f"{size / 1e3:.0f} kB"


def _shown(path: pathlib.Path) -> str:
    try:
        return path.relative_to(REPO).as_posix()
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("notebooks", nargs="*", type=pathlib.Path,
                        help="notebooks to run (default: every notebooks/*.ipynb)")
    parser.add_argument("--check", action="store_true",
                        help="run nothing; list the notebooks whose stamp is stale (exit 1)")
    parser.add_argument("--allow-fallback", action="store_true",
                        help="run without the shared El Centro record (synthetic fallback)")
    parser.add_argument("--dpi", type=int, default=DPI, help=f"PNG resolution ({DPI})")
    parser.add_argument("--full-colour", action="store_true",
                        help="keep matplotlib's PNGs as they are (no 256-colour palette)")
    parser.add_argument("--timeout", type=int, default=TIMEOUT,
                        help=f"seconds per cell ({TIMEOUT})")
    args = parser.parse_args(argv)
    paths = [p.resolve() for p in args.notebooks] or sorted(NOTEBOOKS.glob("*.ipynb"))
    if not paths:
        print("no notebook found", file=sys.stderr)
        return 1

    if args.check:
        import nbformat

        stale = [p for p in paths if not is_fresh(nbformat.read(p, as_version=4))]
        for p in stale:
            print(f"stale: python notebooks/execute.py {_shown(p)}")
        print(f"{len(paths) - len(stale)} of {len(paths)} notebooks fresh")
        return 1 if stale else 0

    _check_kernel_imports_this_checkout()
    record = shared_el_centro()
    if not record.is_file():
        print(f"WARNING: the shared El Centro record {record} is missing; notebooks that read "
              "it are " + ("run on the synthetic fallback" if args.allow_fallback else
                           "refused"), file=sys.stderr)
    failures = 0
    start = time.perf_counter()
    for path in paths:
        t0 = time.perf_counter()
        ok, message = refresh(path, allow_fallback=args.allow_fallback, dpi=args.dpi,
                              shrink=not args.full_colour, timeout=args.timeout)
        failures += not ok
        print(f"{_shown(path)}: {'ok' if ok else 'FAILED'} in {time.perf_counter() - t0:.0f} s: "
              f"{message}", flush=True)
    print(f"{len(paths) - failures} of {len(paths)} notebooks refreshed in "
          f"{time.perf_counter() - start:.0f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
