"""A sweep written to a Zarr store as it goes (`rockjax.sweep_store`, `sweep(store=)`,
`rockjax sweep --store`): the values of the in-memory sweep, units and provenance, an
interrupted sweep resumed into the store of an uninterrupted one (compared with
`xarray.testing.assert_identical` and file by file, byte for byte), and a rerun with other
arguments refused naming the argument.

Two small records (two columns, 0.02 s; 1.6 s and 1.2 s) x 9 scales, chunks of 6 runs
(3 scales x 2 records, padded to 8 runs): every store in the file runs one compiled
program, and the in-memory sweep a second.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import pathlib

import numpy as np
import pytest
from helpers.records import synthetic, write_two_column

import rockjax
from rockjax import _store, _sweep
from rockjax.cli import main

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

SCALES = np.linspace(0.5, 2.5, 9)
#: the arguments of every sweep of the file (the command line's --substeps 2 --tail 0.5)
KW = {"substeps": 2, "tail": 0.5, "chunk_runs": 6, "fidelity_warning": False}


def _files(path):
    """{relative path: SHA-256} of every file of a store."""
    path = pathlib.Path(path)
    return {str(f.relative_to(path)): hashlib.sha256(f.read_bytes()).hexdigest()
            for f in sorted(path.rglob("*")) if f.is_file()}


def _main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """The record files, the records read, and the in-memory sweep and a whole store of
    them (Table 1 column)."""
    d = tmp_path_factory.mktemp("store")
    files = [write_two_column(d / "a.txt", synthetic(seed=5, dt=0.02, duration=1.6, pga=3.0)),
             write_two_column(d / "b.txt", synthetic(seed=6, dt=0.02, duration=1.2, pga=2.0))]
    recs = [rockjax.read_record(f) for f in files]
    s = rockjax.mcmanus_column()
    mem = rockjax.sweep(s, recs, SCALES, **{k: v for k, v in KW.items() if k != "chunk_runs"})
    stored = rockjax.sweep(s, recs, SCALES, store=d / "whole.zarr", **KW)
    return {"dir": d, "files": files, "records": recs, "structure": s, "mem": mem,
            "stored": stored, "whole": d / "whole.zarr"}


def test_store_holds_the_in_memory_sweep_with_units_and_provenance(inputs):
    """`sweep(store=)` returns the in-memory sweep's values, bit for bit; xarray reads the
    store on (structure, record, scale) with units, the done mask, the records' checksums
    and the parameters."""
    mem, stored = inputs["mem"], inputs["stored"]
    for f in _sweep.SWEEP_FIELDS:
        np.testing.assert_array_equal(getattr(stored, f), getattr(mem, f), err_msg=f)
    ds = xr.open_zarr(inputs["whole"], consolidated=False)
    assert ds.peak_u.dims == ("structure", "record", "scale")
    assert ds.sizes == {"structure": 1, "record": 2, "scale": 9}
    assert ds.record.values.tolist() == list(mem.labels)
    np.testing.assert_array_equal(ds.scale.values, SCALES)
    for f in _sweep.SWEEP_FIELDS:
        np.testing.assert_array_equal(ds[f].values[0], getattr(mem, f), err_msg=f)
    assert ds.status.dtype == np.int8 and bool(ds.done.all())
    assert {f: ds[f].attrs.get("units") for f in ("peak_u", "peak_uplift", "t_overturn",
                                                  "t_end", "n_impacts")} == {
        "peak_u": "m", "peak_uplift": "m", "t_overturn": "s", "t_end": "s", "n_impacts": "1"}
    assert ds.status.attrs["flag_meanings"].split() == list(rockjax.STATUS)
    assert ds.record_dt.attrs["units"] == "s" and ds.record_pga.attrs["units"] == "g"
    a = ds.attrs
    assert a["rockjax_version"] == rockjax.__version__ and "jax" in a["software"]
    assert a["command"] == "rockjax.sweep_store (Python)"
    assert a["model"]["model"] == "simplified" and a["integrator"]["substeps"] == 2
    assert [r["label"] for r in a["records"]] == list(mem.labels)
    assert a["records"][0]["sha256"] == ds.record_sha256.values[0] and len(
        a["records"][0]["sha256"]) == 64
    assert a["parameters"]["tail"] == 0.5 and a["parameters"]["chunk_runs"] == 6
    assert a["structures"]["structure"]["k_f"] == inputs["structure"].k_f


def test_an_interrupted_sweep_resumes_into_the_same_store(inputs, monkeypatch, capsys):
    """Stopped after 2 of 6 chunks (two structures, 3 chunks each), the store holds those
    runs and marks only them done (the others are NaN / -1); the same call again runs the
    rest, with a bar of the runs done, and leaves the files of an uninterrupted run, byte
    for byte."""
    s = inputs["structure"]
    both = [s, s.replace(k_f=2 * s.k_f)]
    args = (both, inputs["records"], SCALES)
    kw = {**KW, "structure_labels": ["column", "stiff"]}
    d = inputs["dir"]
    whole = rockjax.sweep_store(d / "two.zarr", *args, **kw)
    calls = []

    def stop(structure, chunk):
        calls.append((structure, chunk))
        if len(calls) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(_sweep, "_AFTER_CHUNK", stop)
    with pytest.raises(KeyboardInterrupt):
        rockjax.sweep_store(d / "cut.zarr", *args, **kw)
    monkeypatch.setattr(_sweep, "_AFTER_CHUNK", None)
    part = xr.open_zarr(d / "cut.zarr", consolidated=False).load()
    assert calls == [(0, 0), (0, 1)]
    assert part.done.values.tolist() == [[True] * 6 + [False] * 3, [False] * 9]
    assert np.isnan(part.peak_u.values[0, :, 6:]).all() and (part.status.values[1] == -1).all()
    np.testing.assert_array_equal(part.peak_u.values[0, :, :6],
                                  inputs["mem"].peak_u[:, :6])
    assert _store.runs_done(d / "cut.zarr") == 12
    resumed = rockjax.sweep_store(d / "cut.zarr", *args, progress=True, **kw)
    assert "sweep" in capsys.readouterr().err  # the bar: runs done / total, time left
    xr.testing.assert_identical(resumed.load(), whole.load())
    assert _files(d / "cut.zarr") == _files(d / "two.zarr")
    np.testing.assert_array_equal(whole.peak_u.values[0], inputs["mem"].peak_u)


@pytest.mark.parametrize("change, param", [
    ({"model": "rigid_body"}, "model"),
    ({"substeps": 4}, "substeps"),
    ({"tail": 1.0}, "tail"),
    ({"chunk_runs": 8}, "chunk_runs"),
    ({"scales": SCALES[:-1]}, "scales"),
    ({"scales": SCALES + 1e-9}, "scales"),
    ({"records": "other"}, "records"),
    ({"structure": "stiffer"}, "structure"),
])
def test_a_rerun_with_other_arguments_is_refused(inputs, change, param):
    """Into a finished store, another model, setting, scale grid, record sample or
    structure field is refused before any run, naming the parameter and both values."""
    rec, s = inputs["records"], inputs["structure"]
    kw = {**KW, **change}
    scales = kw.pop("scales", SCALES)
    if kw.pop("records", None):
        rec = [rec[0], rockjax.Record(dt=rec[1].dt, accel=rec[1].accel * 1.001,
                                      source=rec[1].source)]
    if kw.pop("structure", None):
        s = s.replace(k_f=s.k_f * 1.01)
    before = _files(inputs["whole"])
    with pytest.raises(rockjax.ParameterError, match="store .* holds a sweep whose") as e:
        rockjax.sweep(s, rec, scales, store=inputs["whole"], **kw)
    assert e.value.param == param and "there" in str(e.value) and "here" in str(e.value)
    assert _files(inputs["whole"]) == before


def test_store_paths_that_are_not_stores(tmp_path, inputs):
    """A folder of other files is refused; a store left half-created (killed while being
    created) is created again; chunk_runs needs a store."""
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    rec, s = inputs["records"], inputs["structure"]
    with pytest.raises(rockjax.ParameterError, match="not a rockjax sweep store") as e:
        rockjax.sweep(s, rec, SCALES, store=other, **KW)
    assert e.value.param == "store"
    half = tmp_path / "half.zarr"
    half.mkdir()
    (half / "zarr.json").write_text(json.dumps({
        "zarr_format": 3, "node_type": "group", "attributes": {
            "rockjax_store": _store._CREATING}}))
    res = rockjax.sweep(s, rec, SCALES, store=half, **KW)
    np.testing.assert_array_equal(res.peak_u, inputs["mem"].peak_u)
    with pytest.raises(rockjax.ParameterError, match="chunk_runs"):
        rockjax.sweep(s, rec, SCALES, chunk_runs=6)


def test_cli_store_resume_and_refusal(inputs, tmp_path, monkeypatch):
    """`rockjax sweep --store`: no CSV unless --out, the command in the store, a rerun
    finds every run done; other --substeps into it: a one-line error naming --substeps;
    `rockjax fragility --store` writes the same store and fits from it."""
    monkeypatch.chdir(tmp_path)
    base = ["sweep", "--record", str(inputs["files"][0]), "--record", str(inputs["files"][1]),
            "--scales", "0.5:2.5:9", "--substeps", "2", "--tail", "0.5", "--chunk-runs", "6",
            "--store", "s.zarr", "--no-fidelity-warning"]
    rc, out, err = _main(base + ["--json"])
    assert rc == 0, err
    info = json.loads(out)
    assert info["store"] == "s.zarr" and info["csv"] is None and info["runs_found_done"] == 0
    assert not (tmp_path / "sweep.csv").exists()
    ds = xr.open_zarr(tmp_path / "s.zarr", consolidated=False)
    assert ds.attrs["command"].startswith("rockjax sweep --record ")
    np.testing.assert_array_equal(ds.peak_u.values[0], inputs["mem"].peak_u)
    rc, out, err = _main(base)
    assert rc == 0, err
    assert "18 of them found done and skipped" in out
    rc, out, err = _main([*base[:8], "4", *base[9:]])
    assert rc == 2 and err.count("\n") == 1
    assert err.startswith("rockjax sweep: error: --substeps: the store s.zarr holds a sweep")
    rc, out, err = _main([*base[:-3], "--json"])  # --chunk-runs without --store
    assert rc == 2 and "--chunk-runs: applies with --store" in err
    frag = ["fragility", *base[1:-3], "--store", "f.zarr", "--bootstrap", "0", "--json"]
    rc, out, err = _main(frag)
    assert rc == 0, err
    assert json.loads(out)["store"] == "f.zarr"
    assert _files(tmp_path / "f.zarr").keys() == _files(tmp_path / "s.zarr").keys()
