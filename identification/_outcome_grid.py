r"""The overturning threshold as a smooth, JAX-traceable function of the parameters.

The lowest amplitude $a_c$ of a pulse that overturns a structure is an implicit function of
its parameters (the root of "overturns" in the amplitude, found by
`rockjax.overturning_spectrum`'s scan and multisection); it has no useful derivative of its
own. `ThresholdGrid` computes it once on a grid with rockjax's batch engine and interpolates
$\ln a_c$ between the nodes with piecewise-cubic Hermite polynomials whose slopes are those
of PCHIP (Fritsch-Carlson: the harmonic mean of the neighbouring differences, zero at a
local extremum, so no overshoot at the step where the overturning mode changes). Along each
axis the interpolant is C¹; the tensor product is evaluated axis by axis. Gradients are
then exact derivatives of the interpolant (`jax.grad`), and the likelihood is
JAX-traceable for the sampler.

- A block of unknown shape (`block_threshold_grid`): a uniform rectangular block of
  slenderness $\alpha$ and half-diagonal $R$ has $p = \sqrt{3g/(4R)}$, and its
  dimensionless threshold $a_c/(g\tan\alpha)$ depends on $x = \omega_p/p$ (or $p\,t_1$ for
  a rectangular pulse) and $\alpha$ only (the restitution is the block's own, Eq. 3, and
  the springs are stiff: `STIFFNESS_RATIO`). The grid is over $(\ln x, \alpha)$, once for
  every block.
- A known structure (`structure_threshold_grid`): $\ln a_c$ over $\ln T$ and the free
  structural parameters ($\ln k_f$, $r$).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

import rockjax

from ._outcome_table import G

STIFFNESS_RATIO = 1000.0
"""A block's springs: $\\sqrt{2k_f/m} = 1000\\,p$ (the rigid limit within about 1 %: the
thresholds of `rigid_body` at 300 p and 1000 p differ by 1-2 %)."""
ALPHA_RANGE = (0.04, 0.64)
"""The slenderness [rad] a block grid covers by default (and the default prior's range)."""
X_RANGE = (0.25, 10.0)
"""The default range of $x = \\omega_p/p$ of a block grid (linear in ln-ln beyond)."""


def uniform_block(alpha, R, *, g=G, mass=1.0, stiffness_ratio=STIFFNESS_RATIO):
    """A uniform rectangular block of slenderness `alpha` [rad] and half-diagonal `R` [m]
    (base 2R sin α, height 2R cos α) as a `rockjax.RockingStructure`: two halves of `mass`
    [kg] at its centroid, each with half the block's centroidal inertia, on springs with
    $\\sqrt{2k_f/m} = $ `stiffness_ratio` $\\cdot p$, $p = \\sqrt{3g/(4R)}$."""
    b, h = R * math.sin(alpha), R * math.cos(alpha)
    inertia = 0.5 * mass * (b * b + h * h) / 3.0
    p = math.sqrt(3 * g / (4 * R))
    k_f = 0.5 * mass * (stiffness_ratio * p) ** 2
    return rockjax.RockingStructure(m_e=mass / 2, m_b=mass / 2, H_e=h, H_b=h, B=b,
                                    I_eg=inertia, I_bg=inertia, k_f=k_f, g=g)


def pulse_x(kind, p, period):
    """The spectrum's abscissa: $\\omega_p/p = 2\\pi/(pT)$, or $p\\,t_1$ (rectangular)."""
    return p * period if kind == "rectangular" else 2 * jnp.pi / (p * period)


def _periods(kind, p, x):
    return x / p if kind == "rectangular" else 2 * np.pi / (p * x)


@dataclasses.dataclass(frozen=True, eq=False)
class ThresholdGrid:
    """$\\ln$ of an overturning threshold on a regular grid, with its interpolant.

    - `axes`: the names of the coordinates ("ln_x", "alpha" for a block; "ln_T", "ln_k_f",
      "r" for a structure); `nodes`: one evenly spaced 1-D array per axis; `values`: the
      ln threshold at the nodes (ln of $a_c/(g\\tan\\alpha)$ for a block, of $a_c$
      [m/s²] for a structure); `extrapolate`: per axis "linear" or "clamp".
    - `kind`, `model`: the pulse and the model; `settings`: how the spectra were run;
      `build_time` [s] and `n_runs`: what building it cost.
    """

    kind: str
    model: str
    axes: tuple
    nodes: tuple
    values: np.ndarray
    extrapolate: tuple
    settings: dict
    build_time: float = 0.0
    n_runs: int = 0

    def __call__(self, *coords):
        """The interpolated ln threshold at `coords` (one per axis, broadcast; JAX)."""
        u = jnp.stack(jnp.broadcast_arrays(*[jnp.asarray(c, float) for c in coords]), -1)
        flat = u.reshape(-1, len(self.axes))
        return self._many(flat).reshape(u.shape[:-1])

    @functools.cached_property
    def _many(self):
        return jax.jit(jax.vmap(self._one))

    def _one(self, u):
        vals = jnp.asarray(self.values)
        idx, ts = [], []
        for a, nodes in enumerate(self.nodes):
            n, h = len(nodes), float(nodes[1] - nodes[0])
            s = (u[a] - float(nodes[0])) / h
            i = jnp.clip(jnp.floor(s), 0, n - 2).astype(int)
            t = s - i
            if self.extrapolate[a] == "clamp":
                t = jnp.clip(t, 0.0, 1.0)
            idx.append(i)
            ts.append(t)
        d = len(self.nodes)
        gather = tuple(jnp.clip(idx[a] + jnp.arange(-1, 3), 0, len(self.nodes[a]) - 1
                                ).reshape((1,) * a + (4,) + (1,) * (d - a - 1))
                       for a in range(d))
        block = vals[gather]
        for a in reversed(range(d)):
            block = _hermite(block, ts[a], idx[a], len(self.nodes[a]))
        return block

    def save(self, path) -> None:
        """Write the grid to `path` (NumPy .npz: the nodes, the values and the rest as
        JSON), for `ThresholdGrid.load` in a later process."""
        meta = {"kind": self.kind, "model": self.model, "axes": list(self.axes),
                "extrapolate": list(self.extrapolate), "settings": self.settings,
                "build_time": self.build_time, "n_runs": self.n_runs, "format": 1}
        arrays = {f"nodes_{i}": np.asarray(n) for i, n in enumerate(self.nodes)}
        with open(path, "wb") as f:
            np.savez(f, values=np.asarray(self.values), meta=np.array(json.dumps(meta)),
                     **arrays)

    @classmethod
    def load(cls, path) -> ThresholdGrid:
        """A grid written by `save` (ValueError naming the file if it is not one)."""
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                nodes = tuple(np.asarray(z[f"nodes_{i}"]) for i in range(len(meta["axes"])))
                values = np.asarray(z["values"])
        except (OSError, KeyError, ValueError) as e:
            raise ValueError(f"{path}: not a threshold grid written by ThresholdGrid.save "
                             f"({e})") from None
        return cls(meta["kind"], meta["model"], tuple(meta["axes"]), nodes, values,
                   tuple(meta["extrapolate"]), meta["settings"], meta["build_time"],
                   meta["n_runs"])

    def summary(self) -> dict:
        """The grid's axes, sizes, ranges and cost (plain values)."""
        return {"kind": self.kind, "model": self.model, "axes": list(self.axes),
                "sizes": [len(n) for n in self.nodes],
                "ranges": [[float(n[0]), float(n[-1])] for n in self.nodes],
                "settings": dict(self.settings), "build_time_s": self.build_time,
                "n_runs": self.n_runs}


def _harmonic(a, b):
    ok = a * b > 0
    return jnp.where(ok, 2 * a * b / jnp.where(ok, a + b, 1.0), 0.0)


def _hermite(v, t, i, n):
    """Cubic Hermite along the last axis of `v` (the values at nodes i-1..i+2, clipped),
    PCHIP slopes (one-sided at the ends), linear beyond the first and last nodes."""
    dm, d0, dp = v[..., 1] - v[..., 0], v[..., 2] - v[..., 1], v[..., 3] - v[..., 2]
    s0 = jnp.where(i == 0, d0, _harmonic(dm, d0))
    s1 = jnp.where(i + 2 > n - 1, d0, _harmonic(d0, dp))
    tc = jnp.clip(t, 0.0, 1.0)
    t2, t3 = tc * tc, tc * tc * tc
    inner = ((2 * t3 - 3 * t2 + 1) * v[..., 1] + (t3 - 2 * t2 + tc) * s0
             + (-2 * t3 + 3 * t2) * v[..., 2] + (t3 - t2) * s1)
    return jnp.where(t < 0, v[..., 1] + s0 * t,
                     jnp.where(t > 1, v[..., 2] + s1 * (t - 1), inner))


def _spectrum(structure, kind, periods, model, rtol, n_scan, r=None):
    sp = rockjax.overturning_spectrum(structure, kind, periods, model=model, r=r,
                                      amplitude_rtol=rtol, n_scan=n_scan, progress=False)
    if np.any(~np.isfinite(sp.amplitude)):
        raise ValueError(f"overturning spectrum: nothing overturned at periods "
                         f"{periods[~np.isfinite(sp.amplitude)]} s up to 1000 g tan(alpha); "
                         "narrow the grid")
    return sp


def block_threshold_grid(kind="one_cosine", *, model="rigid_body", alphas=None, x=None,
                         amplitude_rtol=5e-3, n_scan=24) -> ThresholdGrid:
    """The dimensionless threshold $\\ln(a_c/(g\\tan\\alpha))$ of a uniform block
    (`uniform_block`) on a grid over $\\ln x$ ($x = \\omega_p/p$, or $p\\,t_1$) and
    $\\alpha$: one `rockjax.overturning_spectrum` per $\\alpha$ node.

    Defaults: `alphas` 7 nodes evenly over `ALPHA_RANGE`, `x` 16 nodes evenly in $\\ln x$
    over `X_RANGE`; the spectra at `amplitude_rtol` 5e-3 and `n_scan` 24. Nodes must be
    evenly spaced (in $\\ln x$ and in $\\alpha$)."""
    kind = rockjax.pulses.KINDS[kind]
    alphas = np.linspace(*ALPHA_RANGE, 7) if alphas is None else np.asarray(alphas, float)
    x = np.geomspace(*X_RANGE, 16) if x is None else np.asarray(x, float)
    _check_even("alphas", alphas)
    _check_even("x (in ln x)", np.log(x))
    start, runs = time.perf_counter(), 0
    values = np.empty((x.size, alphas.size))
    for j, a in enumerate(alphas):
        s = uniform_block(float(a), 1.0)
        p = math.sqrt(float(s.W * s.R_c / s.I_O))
        sp = _spectrum(s, kind, _periods(kind, p, x), model, amplitude_rtol, n_scan)
        values[:, j] = np.log(sp.normalised)
        runs += sp.n_runs
    return ThresholdGrid(kind, model, ("ln_x", "alpha"), (np.log(x), alphas), values,
                         ("linear", "clamp"),
                         {"amplitude_rtol": amplitude_rtol, "n_scan": n_scan,
                          "stiffness_ratio": STIFFNESS_RATIO},
                         time.perf_counter() - start, runs)


def structure_threshold_grid(structure, kind="one_cosine", *, periods, free=("k_f", "r"),
                             model="rigid_body", k_f_range=None, r_range=(0.3, 0.98),
                             n_periods=16, n_k_f=6, n_r=5, amplitude_rtol=3e-3,
                             n_scan=24) -> ThresholdGrid:
    """$\\ln a_c$ [m/s²] of a known `structure` on a grid over $\\ln T$ (`n_periods` nodes
    from 0.8 min to 1.25 max of `periods` [s]) and its free parameters among "k_f"
    ($\\ln k_f$, `n_k_f` nodes over `k_f_range`, default a tenth to ten times the
    structure's) and "r" (`n_r` nodes over `r_range`): one
    `rockjax.overturning_spectrum` per node of (k_f, r)."""
    kind = rockjax.pulses.KINDS[kind]
    bad = sorted(set(free) - {"k_f", "r"})
    if bad:
        raise ValueError(f"free structural parameters {bad}: k_f and r only")
    periods = np.asarray(periods, float)
    lnT = np.linspace(math.log(0.8 * periods.min()), math.log(1.25 * periods.max()),
                      n_periods)
    k0 = float(structure.k_f)
    k_f_range = (k0 / 10, k0 * 10) if k_f_range is None else k_f_range
    axes, nodes, extra = ["ln_T"], [lnT], ["linear"]
    if "k_f" in free:
        axes.append("ln_k_f")
        nodes.append(np.linspace(math.log(k_f_range[0]), math.log(k_f_range[1]), n_k_f))
        extra.append("clamp")
    if "r" in free:
        axes.append("r")
        nodes.append(np.linspace(*r_range, n_r))
        extra.append("clamp")
    start, runs = time.perf_counter(), 0
    values = np.empty([len(n) for n in nodes])
    for index in np.ndindex(*values.shape[1:]):
        point = dict(zip(axes[1:], (nodes[a + 1][i] for a, i in enumerate(index))))
        s = structure.replace(k_f=math.exp(point["ln_k_f"])) if "ln_k_f" in point else structure
        sp = _spectrum(s, kind, np.exp(lnT), model, amplitude_rtol, n_scan, r=point.get("r"))
        values[(slice(None), *index)] = np.log(sp.amplitude)
        runs += sp.n_runs
    return ThresholdGrid(kind, model, tuple(axes), tuple(nodes), values, tuple(extra),
                         {"amplitude_rtol": amplitude_rtol, "n_scan": n_scan,
                          "structure": structure.to_dict()},
                         time.perf_counter() - start, runs)


def _check_even(name, a):
    if a.ndim != 1 or a.size < 2 or not np.allclose(np.diff(a), a[1] - a[0], rtol=1e-6) or \
            a[1] <= a[0]:
        raise ValueError(f"{name}: at least 2 increasing, evenly spaced nodes expected")
