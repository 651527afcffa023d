"""Matplotlib figures in the style of the paper (Figs 6 and 8)."""

from __future__ import annotations

import numpy as np


def new_figure(**kwargs):
    """A matplotlib Figure that needs no pyplot state or backend switch.

    It saves with `fig.savefig(...)` from scripts and the CLI, and shows inline in notebooks.
    """
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def pushover_curves(structure, umax=None, n=401):
    """The closed-form and numerical pushover curves on u in [0, umax] [m] (numpy arrays)."""
    import jax.numpy as jnp

    from ._pushover import pushover
    from ._restoring import restoring_force

    s = structure
    if umax is None:
        umax = 0.99 * float(s.u_overturn)
    u = jnp.linspace(0.0, umax, n)
    num = pushover(s, u)
    return {
        "u": np.asarray(u),
        "simplified": np.asarray(restoring_force(s, u, "simplified")),
        "exact": np.asarray(restoring_force(s, u, "exact")),
        "numerical": np.asarray(num.P),
        "uplift": np.asarray(num.uplift),
        "theta": np.asarray(num.theta),
        "converged": bool(np.all(np.asarray(num.converged))),
    }


def plot_pushover(structure, curves=None, *, ax=None, title=None):
    """Fig. 6/8-style plot: simplified, exact and numerical k(u), with u_crit, P_crit and
    u_overturn marked. Returns the matplotlib Figure."""
    s = structure
    if curves is None:
        curves = pushover_curves(s)
    if ax is None:
        fig = new_figure(figsize=(7, 4.5))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    u_mm = 1e3 * curves["u"]
    ax.plot(
        u_mm, 1e-3 * curves["numerical"], color="0.6", lw=4, label="numerical pushover (rigid body)"
    )
    ax.plot(u_mm, 1e-3 * curves["exact"], color="C0", lw=1.5, label="exact: Eqs 13, 18")
    ax.plot(
        u_mm, 1e-3 * curves["simplified"], "--", color="C3", lw=1.5, label="simplified: Eqs 13, 20"
    )
    uc, pc, uo = float(s.u_crit), float(s.P_crit), float(s.u_overturn)
    ax.plot([1e3 * uc], [1e-3 * pc], "ko", ms=5)
    ax.annotate(
        f"$u_{{crit}}$ = {1e3 * uc:.2f} mm\n$P_{{crit}}$ = {pc:.0f} N",
        (1e3 * uc, 1e-3 * pc),
        xytext=(25, -5),
        textcoords="offset points",
        fontsize=9,
    )
    ax.axvline(1e3 * uo, color="k", lw=0.8, ls=":")
    ax.annotate(
        f"$u_{{overturn}}$ = {1e3 * uo:.1f} mm",
        (1e3 * uo, 0.0),
        xytext=(-110, 20),
        textcoords="offset points",
        fontsize=9,
    )
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("top displacement u [mm]")
    ax.set_ylabel("restoring force k(u) [kN]")
    ax.set_title(title or "Pushover of a rigid rocking structure on two springs")
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
