"""`Posterior.plot`: trace plots and a pair plot with the Laplace ellipses."""

from __future__ import annotations

import numpy as np


def plot_posterior(post, pair=("k_f", "r"), fig=None):
    """Trace plots of every parameter (a line per chain), and the pair plot of `pair`
    (draws, and the Laplace 1- and 2-sigma ellipses around the fit's values) when both
    are parameters. Returns the figure."""
    import matplotlib.pyplot as plt

    names = post.names
    have_pair = pair is not None and all(p in names for p in pair)
    rows = len(names)
    if fig is None:
        fig = plt.figure(figsize=(11 if have_pair else 7, 1.8 * rows + 0.6))
    gs = fig.add_gridspec(rows, 2 if have_pair else 1,
                          width_ratios=[1.6, 1] if have_pair else None)
    for i, n in enumerate(names):
        ax = fig.add_subplot(gs[i, 0])
        for c, x in enumerate(post.chains_draws[n]):
            ax.plot(x, lw=0.6, alpha=0.8, label=f"chain {c}")
        unit = post.units.get(n, "")
        ax.set_ylabel(f"{n} [{unit}]" if unit and unit != "-" else n)
        ax.set_title(f"{n}: R-hat {post.rhat[n]:.3f}, ESS {post.ess[n]:.0f}", fontsize=8,
                     loc="left")
        if i == rows - 1:
            ax.set_xlabel("draw (after warmup)")
        else:
            ax.tick_params(labelbottom=False)
    if have_pair:
        a, b = pair
        ax = fig.add_subplot(gs[:, 1])
        for c in range(post.chains_draws[a].shape[0]):
            ax.plot(post.chains_draws[a][c], post.chains_draws[b][c], ".", ms=2, alpha=0.4,
                    label=f"chain {c}")
        ia, ib = names.index(a), names.index(b)
        cov = np.asarray(post.laplace["cov"])[np.ix_([ia, ib], [ia, ib])]
        mu = np.array([post.laplace["value"][a], post.laplace["value"][b]])
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        t = np.linspace(0, 2 * np.pi, 200)
        circle = np.stack([np.cos(t), np.sin(t)])
        for k, style in ((1, "-"), (2, "--")):
            e = mu[:, None] + k * (vecs * np.sqrt(np.maximum(vals, 0))) @ circle
            ax.plot(e[0], e[1], "k" + style, lw=1.2,
                    label=f"Laplace {k} sigma" if k == 1 else f"{k} sigma")
        ax.plot(*mu, "k+", ms=10, label="fit (Laplace centre)")
        ax.set_xlabel(f"{a} [{post.units.get(a, '')}]")
        ax.set_ylabel(f"{b} [{post.units.get(b, '')}]")
        ax.set_title("draws and the Laplace ellipses", fontsize=9)
        ax.legend(fontsize=7, markerscale=3)
    title = f"posterior ({post.source or 'fit'}), NUTS"
    if not post.ok:
        title = "WARNING: diagnostics FAIL. " + title
    fig.suptitle(title, color="k" if post.ok else "red")
    fig.tight_layout()
    return fig
