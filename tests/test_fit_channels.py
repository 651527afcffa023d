"""Traces of any channel (issue 24): a rotation alone, an uplift alone, or u with the
rotation, each fitted through the model's own observation of it (`Response.theta`,
`Response.uplift`), recover k_f and r; what cannot be fitted is refused, saying why.

The traces are `rockjax.simulate` of Table 1's column released at 80 mm (3 s at 5 ms,
white noise of 0.2 mm or 0.2 mrad), fitted from k_f 20 % low: one simulation for the
module, one compile per set of channels (about 15 s each on two cores).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import identification
import rockjax

U0 = 0.08
NOISE = 2e-4


@pytest.fixture(scope="module")
def column():
    return rockjax.mcmanus_column()


@pytest.fixture(scope="module")
def motion(column):
    """(t, u, theta, uplift) with noise, of a release at U0 from rest at t = 0."""
    ts = np.arange(0.0, 3.0 + 1e-9, 0.005)
    res = rockjax.simulate(column, rockjax.FreeVibration(U0), ts[-1], ts=ts,
                           r=float(column.restitution))
    rng = np.random.default_rng(7)
    return ts, *(np.asarray(x) + rng.normal(0.0, NOISE, ts.size)
                 for x in (res.u, res.theta, res.uplift))


def _fit(column, **channels):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning: converged, residuals noise
        return identification.fit_decay(identification.DecayTrace(**channels),
                                         column.replace(k_f=0.8 * float(column.k_f)))


def _check_recovery(fit, column, tol_kf):
    assert fit.converged and not fit.lack_of_fit["fires"]
    k_err = fit.values["k_f"] / float(column.k_f) - 1
    r_err = fit.values["r"] / float(column.restitution) - 1
    assert abs(k_err) < tol_kf, k_err
    assert abs(r_err) < 0.005, r_err
    assert fit.values["u0"] == pytest.approx(U0, rel=0.005)
    # the standard errors cover the truth (3 sigma)
    assert abs(fit.values["k_f"] - float(column.k_f)) < 3 * fit.stderr["k_f"]


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_rotation_only_trace(column, motion):
    """theta alone: the release is found in the rotation, u0 maps to the initial rotation,
    the rotation's zero is a nuisance parameter (offset_theta [rad])."""
    t, u, theta, up = motion
    fit = _fit(column, t=t, theta=theta)
    assert fit.channels == ("theta",)
    assert fit.names == ("k_f", "r", "u0", "t0", "offset_theta")
    _check_recovery(fit, column, 0.02)
    assert abs(fit.values["offset_theta"]) < 3 * fit.stderr["offset_theta"]
    assert fit.sigma == pytest.approx(NOISE, rel=0.1)  # of the rotation [rad]
    assert fit.summary()["units"]["sigma"] == "rad"
    assert fit.release["channel"] == "theta"


@pytest.mark.slow  # a compile of its own (~20 s); the rotation-only fit stays in the default suite
def test_uplift_only_trace(column, motion):
    """The uplift alone pins k_f too: the time spent in contact between lift-offs (the
    springs' oscillation, zero uplift) depends on it, and the landings pin the zero."""
    t, u, theta, up = motion
    fit = _fit(column, t=t, uplift=up)
    assert fit.channels == ("uplift",)
    assert "offset_uplift" in fit.names and "offset" not in fit.names
    _check_recovery(fit, column, 0.03)


@pytest.mark.slow  # a compile of its own (~20 s); the rotation-only fit stays in the default suite
def test_displacement_and_rotation_trace(column, motion):
    """u and theta together: two residual channels, each with its own zero."""
    t, u, theta, up = motion
    fit = _fit(column, t=t, u=u, theta=theta)
    assert fit.channels == ("u", "theta")
    assert fit.names == ("k_f", "r", "u0", "t0", "offset", "offset_theta")
    _check_recovery(fit, column, 0.02)
    assert fit.sigma == pytest.approx(NOISE, rel=0.1)  # of u [m]


def test_channels_refused_with_reasons(column, motion):
    """Cheap refusals (before any compile): an uplift-only trace that starts in contact
    (its release cannot be found), a structure that never lifts off, a drift or an offset
    of a channel the trace lacks, a joint fit of rotation traces."""
    t, u, theta, up = motion
    late = np.flatnonzero(np.asarray(up) < 0.5 * NOISE)[0]  # in contact after the release
    tr = identification.DecayTrace(t=t[late:], uplift=up[late:])
    with pytest.raises(identification.TraceError, match=r"release cannot be found in the "
                       r"uplift.*initial=\{'u0'"):
        identification.fit_decay(tr, column)
    with pytest.raises(ValueError, match="uplift is zero everywhere"):
        identification.fit_decay(identification.DecayTrace(t=t, uplift=0 * t), column)
    with pytest.raises(ValueError, match="drift is a parameter of a channel the fit does "
                       "not have"):
        identification.fit_decay(identification.DecayTrace(t=t, theta=theta), column,
                                 drift=True)
    with pytest.raises(ValueError, match="offset is a parameter of a channel"):
        identification.fit_decay(identification.DecayTrace(t=t, theta=theta), column,
                                 params=("k_f", "offset"))
    with pytest.raises(ValueError, match="a joint fit takes traces of u"):
        identification.fit_decay([identification.DecayTrace(t=t, theta=theta)] * 2, column)
    with pytest.raises(identification.TraceError, match=r"max \|theta\| = .* beyond the "
                       r"rotation at which the structure overturns"):
        identification.fit_decay(identification.DecayTrace(t=t, theta=57.3 * theta), column)


def test_release_in_the_rotation(column, motion):
    """detect_release finds a hold in the rotation as in u (level in rad)."""
    t, u, theta, up = motion
    held = np.concatenate([np.full(100, theta[0]) + np.random.default_rng(1).normal(
        0, NOISE, 100), theta])
    th_t = np.concatenate([t[0] - 0.005 * np.arange(100, 0, -1), t]) + 1.0
    rel = identification.detect_release(identification.DecayTrace(t=th_t, theta=held))
    assert rel.channel == "theta" and rel.held
    assert rel.time == pytest.approx(1.0, abs=0.01)
    assert rel.level == pytest.approx(float(rockjax.theta_from_u(column, U0)), rel=0.01)
    assert "level_rad" in rel.as_dict()


@pytest.mark.slow  # a compile of its own (~20 s); the rotation-only fit stays in the default suite
def test_cli_reads_a_rotation_column(column, motion, tmp_path, capsys):
    """`rockjax fit --columns t=t,theta=NAME` fits the rotation (in degrees here); the
    report gives the rms residual in rad. In process: the rotation fit above compiled it."""
    t, u, theta, up = motion
    csv = tmp_path / "rot.csv"
    csv.write_text("t,Winkel_deg,other\n" + "".join(
        f"{a:.6f},{np.degrees(b):.9f},0\n" for a, b in zip(t, theta)))
    from rockjax.cli import main

    rc = main(["fit", str(csv), "--columns", "t=t,theta=Winkel_deg"], compile_cache=False)
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "theta = column 'Winkel_deg' in deg (header)" in out
    assert "offset_theta" in out and " rad  (noise sigma estimate" in out
    k_f = float(next(ln.split()[1] for ln in out.splitlines() if ln.startswith("k_f ")))
    assert k_f == pytest.approx(float(column.k_f), rel=0.02)


@pytest.mark.slow  # compile-bound (~14 s); tests/test_plotting.py checks the fit plots
def test_plot_of_a_rotation_fit(column, motion):
    """`plot_fit` draws the channels the trace has (a rotation alone: in mrad)."""
    t, u, theta, up = motion
    tr = identification.DecayTrace(t=t, theta=theta)
    fit = _fit(column, t=t, theta=theta)  # compiled above: no new compile
    from rockjax._plotting import plot_fit  # what `rockjax fit --plot` draws

    fig = plot_fit(tr, fit)
    axes = fig.get_axes()
    assert len(axes) == 2 and axes[0].get_ylabel() == "rotation θ [mrad]"
    assert axes[1].get_ylabel() == "residual [mrad]"
    assert "mrad, converged" in axes[0].get_title()
