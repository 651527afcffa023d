"""The command line: demo, pushover --json, and one-line errors without tracebacks."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from conftest import run_cli

import rockjax
from rockjax import G_STANDARD
from rockjax.cli import main


def test_help():
    r = run_cli("--help")
    assert r.returncode == 0 and "pushover" in r.stdout and "demo" in r.stdout
    r = run_cli("pushover", "--help")
    assert r.returncode == 0 and "--umax" in r.stdout and "--json" in r.stdout


def test_pushover_json(capsys, column):
    assert main(["pushover", "--json", "--points", "200"]) == 0
    out = json.loads(capsys.readouterr().out)
    d = out["derived"]
    for k in column.derived():
        assert d[k] == pytest.approx(column.derived()[k], rel=1e-12)
    for k in ("alpha_c_deg", "alpha_e_deg", "alpha_b_deg"):
        assert k in d
    c = out["curve"]
    assert len(c["u"]) == 200 and set(c) == {"u", "simplified", "exact", "numerical"}
    assert c["u"][0] == 0.0 and c["u"][-1] == pytest.approx(0.99 * d["u_overturn"])
    err = max(
        abs(a - b)
        for a, b, u in zip(c["exact"], c["numerical"], c["u"])
        if 1.2 * d["u_crit"] <= u <= 0.95 * d["u_overturn"]
    )
    assert err < 1e-3 * d["P_crit"]


def test_pushover_table_plot_and_csv(tmp_path, capsys):
    png, csv = tmp_path / "p.png", tmp_path / "p.csv"
    assert main(["pushover", "--umax", "0.2", "--plot", str(png), "--out", str(csv)]) == 0
    text = capsys.readouterr().out
    assert "u_crit" in text and "restitution" in text
    assert png.stat().st_size > 10_000
    lines = csv.read_text().splitlines()
    assert lines[0] == "u_m,simplified_N,exact_N,numerical_N,theta_rad,uplift_m"
    assert len(lines) == 202


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_demo_writes_plots(tmp_path, capsys, monkeypatch, ground_motions_dir):
    """The demo on the real El Centro record (skips without the shared folder): the
    paper's Fig. 10 case, 243 impacts. test_demo_falls_back_to_synthetic runs it without."""
    monkeypatch.setenv("ROCKJAX_EL_CENTRO", str(ground_motions_dir / "IELC180.AT2"))
    monkeypatch.setenv("ROCKJAX_CACHE", str(tmp_path / "cache"))
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    for name in ("pushover.png", "free_vibration.png", "earthquake.png"):
        assert (tmp_path / "demo" / name).stat().st_size > 10_000
    out = capsys.readouterr().out
    assert "P_crit" in out and "El Centro" in out and "SYNTHETIC" not in out
    assert "IELC180.AT2: units g (file header), dt 0.01 s, 4000 points" in out
    row = next(ln for ln in out.splitlines() if ln.startswith("earthquake, simplified SDOF"))
    assert row.split()[-2] == "243" and row.split()[-1] == "completed"
    rigid = next(ln for ln in out.splitlines() if ln.startswith("earthquake, 2-DOF body"))
    assert float(rigid.split()[-4]) < 0.5 * float(row.split()[-4])  # the fidelity finding
    body = next(ln for ln in out.splitlines() if ln.startswith("earthquake, rigid_body"))
    assert body.split()[-1] == "completed" and float(body.split()[-4]) < float(row.split()[-4])


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_demo_falls_back_to_synthetic(tmp_path, capsys, monkeypatch):
    from rockjax import datasets

    def offline(url, dest):
        raise OSError("network unreachable")

    monkeypatch.delenv("ROCKJAX_EL_CENTRO", raising=False)
    monkeypatch.setenv("ROCKJAX_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(datasets, "_download", offline)
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "SYNTHETIC" in out and (tmp_path / "demo" / "earthquake.png").exists()


def test_simulate_free_vibration_json(capsys):
    assert main(["simulate", "--u0", "0.1", "--t1", "4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"peak_u", "t_peak", "peak_theta", "peak_theta_over_alpha_c", "peak_uplift",
            "n_impacts", "impact_times", "status", "message", "t_overturn", "t_end",
            "residual_u", "model", "impact", "r", "excitation", "units"} <= set(out)
    assert out["model"] == "simplified" and out["impact"] == "paper" and out["r_from"] == "Eq 3"
    assert out["excitation"] == {"type": "free_vibration", "u0": 0.1, "v0": 0.0}
    assert out["units"]["peak_u"] == "m" and out["units"]["t_peak"] == "s"
    assert out["status"] == "completed" and out["t_overturn"] is None
    assert out["peak_u"] == pytest.approx(0.1) and out["n_impacts"] == len(out["impact_times"])
    assert out["n_impacts"] == 17


def write_at2(path, record):
    """`record` (m/s²) as a PEER AT2 file in g, five values a line like IELC180.AT2."""
    g = np.asarray(record.accel) / G_STANDARD
    rows = [" ".join(f"{x:15.7E}" for x in g[i:i + 5]) for i in range(0, len(g), 5)]
    header = ["SYNTHETIC GROUND MOTION (rockjax.datasets.synthetic_ground_motion)",
              record.source, "ACCELERATION TIME HISTORY IN UNITS OF G",
              f"NPTS= {len(g)}, DT= {record.dt:.5f} SEC"]
    path.write_text("\n".join(header + rows) + "\n")
    return path


def test_simulate_record_csv_plot(tmp_path, capsys, synthetic_record):
    """A record file (the generated test record written as an AT2 file in g)."""
    rec = write_at2(tmp_path / "synthetic.AT2", synthetic_record)
    csv, png = tmp_path / "r.csv", tmp_path / "r.png"
    args = ["simulate", "--record", str(rec), "--units", "g", "--scale", "0.5", "--t1", "10",
            "--model", "exact", "--out", str(csv), "--plot", str(png)]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "synthetic.AT2: units g" in text  # the record read back: El Centro's PGA
    assert "4001 points, 40 s, PGA 0.3128 g x scale 0.5" in text
    assert "status        completed" in text
    lines = csv.read_text().splitlines()
    assert lines[0] == "t_s,u_m,v_m_s,theta_rad,uplift_m"
    assert len(lines) == 1002  # 0.01 s grid, 10 s
    assert png.stat().st_size > 10_000


def test_simulate_overturns_json(capsys):
    assert main(["simulate", "--u0", "0.37", "--v0", "0.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "overturned" and 0.0 < out["t_overturn"] < 0.1
    assert out["t_peak"] == out["t_overturn"] and out["residual_u"] is None
    assert out["peak_theta_over_alpha_c"] == pytest.approx(1.0, abs=1e-4)


SOFT = "[structure]\nm_e=1.0\nm_b=1.0\nH_e=1.0\nH_b=0.1\nB=0.3\nI_eg=0.0\nI_bg=0.0\nk_f=10.0\n"
NEG = SOFT.replace("m_e=1.0", "m_e=-1.0").replace("k_f=10.0", "k_f=1e6")


@pytest.mark.parametrize(
    "args, files, match",
    [
        (["pushover", "--structure", "soft.toml"], {"soft.toml": SOFT}, "k_f is too soft"),
        (["pushover", "--structure", "neg.toml"], {"neg.toml": NEG}, "m_e"),
        (["pushover", "--structure", "missing.toml"], {}, "not found"),
        (["pushover", "--structure", "bad.toml"], {"bad.toml": "[structure\n"}, "TOML"),
        (["pushover", "--umax", "-1"], {}, "--umax"),
        (["pushover", "--umax", "abc"], {}, "--umax"),
        (["pushover", "--points", "1"], {}, "--points"),
        (["pushover", "--plot", "x.txt"], {}, "--plot"),
        (["pushover", "--bogus"], {}, "unrecognized"),
        (["nosuchcommand"], {}, "invalid choice"),
        (["simulate"], {}, "give --u0"),
        (["simulate", "--u0", "0.1", "--record", "x.at2"], {}, "not both"),
        (["simulate", "--u0", "0.1", "--r", "1.5"], {}, "--r"),
        (["simulate", "--u0", "0.1", "--t1", "0"], {}, "--t1"),
        (["simulate", "--u0", "0.1", "--model", "fancy"], {}, "--model"),
        (["simulate", "--record", "missing.at2"], {}, "not found"),
        (["simulate", "--record", "bad.at2"], {"bad.at2": "a\nb\nc\nNPTS= 3, DT= .01\n1 2\n"},
         "NPTS"),
        (["simulate", "--record", "nan.txt", "--units", "g"],
         {"nan.txt": "0 0.1\n0.01 nan\n0.02 0.1\n"}, "NaN"),
        (["simulate", "--record", "one.txt", "--units", "g"], {"one.txt": "0.1\n0.2\n0.3\n"},
         "dt"),
    ],
)
def test_cli_errors_one_line_no_traceback(tmp_path, args, files, match):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    r = run_cli(*args, cwd=tmp_path)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert match in lines[0]


def test_in_process_main_leaves_the_jax_configuration_alone(monkeypatch, capsys):
    """`main([...])` from Python does not turn on the persistent compilation cache of the
    calling process; the command itself (argv None) and `compile_cache=True` do."""
    import jax

    import rockjax.cli as cli

    before = jax.config.jax_compilation_cache_dir
    assert main(["pushover", "--json", "--points", "50"]) == 0  # the real function
    assert jax.config.jax_compilation_cache_dir == before
    calls = []
    monkeypatch.setattr(cli, "enable_compile_cache", lambda disabled=False: calls.append(disabled))
    assert main(["pushover", "--json", "--points", "50"]) == 0 and calls == []
    assert main(["pushover", "--json", "--points", "50"], compile_cache=True) == 0
    assert main(["--no-compile-cache", "pushover", "--json", "--points", "50"],
                compile_cache=True) == 0
    monkeypatch.setattr("sys.argv", ["rockjax", "pushover", "--json", "--points", "50"])
    assert main() == 0
    assert calls == [False, True, False]
    capsys.readouterr()


# ------------------------------------------- library errors name the command's option
#: the least arguments each command parses with
_MINIMAL = {"demo": [], "pushover": [], "simulate": [], "fit": ["t.csv"],
            "fit-table": ["run.csv"],
            "sweep": ["--record", "r.txt"], "fragility": ["--record", "r.txt", "--scales", "1"],
            "spectrum": ["--pulse", "sine", "--ratios", "1"], "fit-outcomes": ["t.csv"],
            "rocking-spectrum": ["--record", "r.txt", "--alpha", "0.2"]}


def _raising(param, **kw):
    def run(args):
        raise rockjax.ParameterError(f"{param} is wrong, got 7", param=param, **kw)
    return run


def _mapped():
    from rockjax.cli import COMMANDS, flags
    for module in COMMANDS:
        command = getattr(module, "COMMAND",
                          module.__name__.rsplit(".", 1)[-1].replace("_", "-"))
        for param, flag in flags(command).items():
            yield module, command, param, flag


@pytest.mark.parametrize("module, command, param, flag", list(_mapped()),
                         ids=lambda x: x if isinstance(x, str) else None)
def test_every_mapped_parameter_reaches_its_option(module, command, param, flag, capsys,
                                                   monkeypatch):
    """A `ParameterError` about `param` reads "--flag: message; pass --flag value" in the
    command that maps `param` to `flag` (no rewriting of the message)."""
    monkeypatch.setattr(module, "run", _raising(param, choices=("v",), omit=True))
    assert main([command, *_MINIMAL[command]]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"rockjax {command}: error: {flag}: {param} is wrong, got 7; omit {flag} "
                   f"or pass {flag} v")
    assert f"{param}=" not in err.replace(f"{flag}", "")


def test_a_parameter_without_an_option_reads_as_the_message(capsys, monkeypatch):
    from rockjax.cli import simulate
    monkeypatch.setattr(simulate, "run", _raising("ts", choices=(1.0,)))
    assert main(["simulate"]) == 2
    # the Python advice ("pass ts=1.0") is left out: the command has no option for ts
    assert capsys.readouterr().err.strip() == "rockjax simulate: error: ts is wrong, got 7"


def test_library_errors_carry_their_parameter():
    s = rockjax.mcmanus_column()
    cases = [
        (lambda: rockjax.simulate(s, rockjax.FreeVibration(0.1), -1.0), "t1"),
        (lambda: rockjax.simulate(s, rockjax.FreeVibration(0.1), 1.0, r=1.5), "r"),
        (lambda: rockjax.sweep(s, [rockjax.datasets.synthetic_ground_motion(
            duration=1.0, dt=0.01, pga=1.0, seed=0)], [-1.0]), "scales"),
        (lambda: rockjax.overturning_spectrum(s, "sine", [-1.0]), "periods"),
        (lambda: rockjax.pulses.one_sine(float("nan"), 0.5), "amplitude"),
        (lambda: rockjax.pulses.one_sine(4.0, -0.5), "period"),
        (lambda: rockjax.spectral_acceleration(np.ones(5), [1.0], zeta=2.0, dt=0.01), "zeta"),
    ]
    for call, param in cases:
        with pytest.raises(rockjax.ParameterError) as e:
            call()
        assert e.value.param == param and isinstance(e.value, ValueError)


def test_one_converter_factory(capsys):
    from rockjax.cli._common import converter
    conv = converter("--n", int, lambda n: n > 2, "be above 2")
    assert conv("3") == 3
    with pytest.raises(argparse.ArgumentTypeError, match="--x must be finite, got 'nan'"):
        converter("--x", float, math.isfinite, "be finite")("nan")
    for text, says in (("x", "--n must be an integer, got 'x'"),
                       (" 1", "--n must be above 2, got 1$")):
        with pytest.raises(argparse.ArgumentTypeError, match=says):
            conv(text)


def test_no_message_rewriting_in_the_cli():
    import pathlib
    import re

    import rockjax.cli
    for path in pathlib.Path(rockjax.cli.__file__).parent.glob("*.py"):
        src = path.read_text()
        assert not re.search(r"^import re$|\bre\.(sub|compile)\(", src, re.M), path.name
        assert "cli_message" not in src and "str(e).replace" not in src, path.name


def test_an_error_about_one_value_names_the_option_and_the_value(capsys, monkeypatch):
    """`ParameterError(value=...)`: "--flag VALUE: message" on the command line, and
    "param='VALUE': message" in Python; it survives pickling."""
    import pickle

    from rockjax.cli import sweep

    error = rockjax.ParameterError("no record files here", param="records", value="quakes/")
    assert str(error) == "records='quakes/': no record files here"
    assert pickle.loads(pickle.dumps(error)).value == "quakes/"

    def run(args):
        raise error

    monkeypatch.setattr(sweep, "run", run)
    assert main(["sweep", "--record", "r.txt"]) == 2
    assert (capsys.readouterr().err.strip()
            == "rockjax sweep: error: --record quakes/: no record files here")


def test_trace_errors_name_the_argument_that_fixes_them(tmp_path):
    """A `TraceError` carries the argument (and a value) that fixes it; the command line
    writes that argument as its own option, the message otherwise unchanged."""
    import identification
    from rockjax.cli import fit
    from rockjax.cli._common import parameter_message

    path = tmp_path / "t.csv"
    path.write_text("time,disp,temp\n0,0.1,3\n")
    with pytest.raises(identification.TraceError) as e:
        identification.read_trace(path)
    assert e.value.param == "columns"
    assert str(e.value).endswith("name the columns with columns={'t': ..., 'u': ...}")
    cli = parameter_message(e.value, fit.FLAGS)
    assert cli == e.value.message + "; name the columns with --columns t=NAME,u=NAME"
    assert parameter_message(e.value, {}) == str(e.value)  # no option: the Python advice


def test_fit_figures_live_in_plotting(tmp_path):
    """`rockjax._plotting.plot_fit` (with the uplift panel when the trace has one) and
    `plot_joint_fit`: the figures of `rockjax fit --plot`, drawn from any fit result."""
    from types import SimpleNamespace

    from rockjax._plotting import plot_fit, plot_joint_fit

    t = np.linspace(0.0, 1.0, 50)
    u, up = 0.05 * np.cos(6 * t), 0.01 * np.abs(np.sin(6 * t))
    fit = SimpleNamespace(names=("k_f", "r"), values={"k_f": 5e5, "r": 0.7},
                          stderr={"k_f": 1e3, "r": 0.01}, converged=True, rms=1e-4,
                          response=SimpleNamespace(u=u + 1e-4, uplift=up))
    with_uplift = plot_fit(SimpleNamespace(t=t, u=u, uplift=up), fit, title="T")
    assert len(with_uplift.axes) == 3 and "k_f = 5e+05" in with_uplift.axes[0].get_title()
    assert len(plot_fit(SimpleNamespace(t=t, u=u, uplift=None), fit).axes) == 2
    joint = SimpleNamespace(**vars(fit), responses=[fit.response] * 2,
                            per_trace=[{"source": "a.csv", "rms": 1e-4}] * 2)
    fig = plot_joint_fit([SimpleNamespace(t=t, u=u)] * 2, joint)
    assert len(fig.axes) == 2
    fig.savefig(tmp_path / "j.png")
    assert (tmp_path / "j.png").stat().st_size > 1000


def test_an_impact_rule_that_cannot_apply_is_refused(tmp_path):
    """`--impact after_uplift` with a model that has its own contact law is refused naming
    --impact (issue 24: it was silently ignored, and the plot said "impact rule ...")."""
    r = run_cli("simulate", "--u0", "0.05", "--model", "rigid_body", "--impact",
                "after_uplift", "--t1", "0.5", cwd=tmp_path)
    assert r.returncode == 2
    assert "--impact: the impact rule 'after_uplift' applies to the SDOF" in r.stderr
    assert r.stderr.rstrip().endswith("omit --impact")
