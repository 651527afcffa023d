"""The command line: demo, pushover --json, and one-line errors without tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from rockjax._cli import main


def run_cli(*args, cwd=None):
    """Run the real console entry point in a subprocess (as a user would)."""
    return subprocess.run(
        [sys.executable, "-m", "rockjax._cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


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
    assert lines[0] == "u,simplified,exact,numerical,theta,uplift" and len(lines) == 202


def test_demo_writes_plot(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    assert (tmp_path / "demo" / "pushover.png").stat().st_size > 10_000
    assert "P_crit" in capsys.readouterr().out


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
