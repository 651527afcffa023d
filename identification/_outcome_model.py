r"""The physics model of topple outcomes: a probit link on the log-ratio of the commanded
amplitude to the model's own overturning threshold,

$$P(\text{topple} \mid A, T) = \Phi\!\left(\frac{\ln A - \ln A_c(T;\theta)}{\beta}\right),$$

$A_c$ from a `ThresholdGrid` (rockjax's overturning spectra, interpolated), $\theta$ the
block's $(\alpha, R)$ or a known structure's $(k_f, r)$. The parameters are optimised in
unconstrained coordinates $z$: $\alpha$, $r$ and $\ln k_f$ mapped into the grid's range by
a logistic function, $R$ and $\beta$ by exp.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import log_ndtr

from ._outcome_grid import pulse_x

BLOCK_PARAMS = ("alpha", "R", "beta")
"""The parameters of a block of unknown shape: slenderness [rad], half-diagonal [m], and
the dispersion of the probit link [-]."""
STRUCTURE_PARAMS = ("k_f", "r", "beta")
"""The parameters of a known structure: spring stiffness [N/m], restitution [-], β [-]."""
UNITS = {"alpha": "rad", "R": "m", "beta": "-", "k_f": "N/m", "r": "-"}


def _sigmoid_map(lo, hi):
    return (lambda z: lo + (hi - lo) * jax.nn.sigmoid(z),
            lambda x: math.log((x - lo) / (hi - x)))


@dataclasses.dataclass(frozen=True, eq=False)
class PhysicsModel:
    """The threshold model of one fit: its grid, pulse kind, free and fixed parameters."""

    grid: object
    kind: str
    names: tuple
    free: tuple
    fixed: dict
    g: float
    structure: object = None

    @property
    def bounds(self) -> dict:
        """name -> (low, high) of the parameters held inside the grid (None: positive)."""
        out = {"R": None, "beta": None}
        for axis, nodes in zip(self.grid.axes, self.grid.nodes):
            if axis == "alpha":
                out["alpha"] = (float(nodes[0]), float(nodes[-1]))
            elif axis == "ln_k_f":
                out["k_f"] = (math.exp(nodes[0]), math.exp(nodes[-1]))
            elif axis == "r":
                out["r"] = (float(nodes[0]), float(nodes[-1]))
        return out

    def _maps(self, name):
        b = self.bounds.get(name)
        if name == "k_f":
            f, inv = _sigmoid_map(math.log(b[0]), math.log(b[1]))
            return (lambda z: jnp.exp(f(z))), (lambda x: inv(math.log(x)))
        if b is None:
            return jnp.exp, math.log
        return _sigmoid_map(*b)

    def to_physical(self, z) -> dict:
        """name -> value of every parameter (free ones from z, JAX-traceable)."""
        out = {n: jnp.asarray(v, float) for n, v in self.fixed.items()}
        for i, n in enumerate(self.free):
            out[n] = self._maps(n)[0](z[i])
        return out

    def to_z(self, values: dict) -> np.ndarray:
        """The unconstrained z of physical values (a start), clipped inside the bounds."""
        z = []
        for n in self.free:
            b = self.bounds.get(n)
            v = float(values[n])
            if b is not None:
                span = b[1] - b[0]
                v = min(max(v, b[0] + 1e-3 * span), b[1] - 1e-3 * span)
            z.append(self._maps(n)[1](v))
        return np.asarray(z, float)

    def log_threshold(self, params: dict, period):
        """$\\ln A_c$ [ln m/s²] of the pulses of `period` [s] (JAX)."""
        period = jnp.asarray(period, float)
        if self.structure is None:
            alpha, R = params["alpha"], params["R"]
            p = jnp.sqrt(3 * self.g / (4 * R))
            x = pulse_x(self.kind, p, period)
            return jnp.log(self.g * jnp.tan(alpha)) + self.grid(jnp.log(x), alpha)
        coords = {"ln_T": jnp.log(period)}
        if "ln_k_f" in self.grid.axes:
            coords["ln_k_f"] = jnp.log(params["k_f"])
        if "r" in self.grid.axes:
            coords["r"] = params["r"]
        return self.grid(*(coords[a] for a in self.grid.axes))

    def log_lik_terms(self, params, amplitude, period, toppled):
        """log P of each run's outcome; a run at zero amplitude stood: log 1 = 0."""
        amplitude = jnp.asarray(amplitude, float)
        pos = amplitude > 0
        s = (jnp.log(jnp.where(pos, amplitude, 1.0)) - self.log_threshold(params, period)
             ) / params["beta"]
        ll = jnp.where(jnp.asarray(toppled) == 1, log_ndtr(s), log_ndtr(-s))
        return jnp.where(pos, ll, 0.0)

    def nll(self, z, amplitude, period, toppled, weight):
        """The weighted negative log-likelihood of z (JAX)."""
        terms = self.log_lik_terms(self.to_physical(z), amplitude, period, toppled)
        return -jnp.sum(weight * terms)

    @functools.cached_property
    def value_and_grad(self):
        """`nll` and its gradient in z, jitted once per model (every fit and fold)."""
        return jax.jit(jax.value_and_grad(self.nll))

    @functools.cached_property
    def jit_probability(self):
        """`probability`, jitted."""
        return jax.jit(self.probability)

    @functools.cached_property
    def jit_mean_probability(self):
        """The mean of `probability` over draws (name -> array; `fixed`: the others)."""
        def mean(draws, fixed, amplitude, period):
            one = jax.vmap(lambda p: self.probability({**fixed, **p}, amplitude, period))
            return jnp.mean(one(draws), axis=0)

        return jax.jit(mean)

    @functools.cached_property
    def jit_log_lik_terms(self):
        """`log_lik_terms`, jitted."""
        return jax.jit(self.log_lik_terms)

    @functools.cached_property
    def jit_log_threshold(self):
        """`log_threshold`, jitted."""
        return jax.jit(self.log_threshold)

    def probability(self, params, amplitude, period):
        """P(topple) of pulses `amplitude` [m/s²] and `period` [s] (JAX, broadcast)."""
        amplitude = jnp.asarray(amplitude, float)
        pos = amplitude > 0
        s = (jnp.log(jnp.where(pos, amplitude, 1.0)) - self.log_threshold(params, period)
             ) / params["beta"]
        return jnp.where(pos, jax.scipy.stats.norm.cdf(s), 0.0)

    def starts(self) -> list:
        """Starting points z of the multi-start optimisation (a grid of plausible values)."""
        if self.structure is None:
            grid = [{"alpha": a, "R": R, "beta": 0.3}
                    for a in (0.08, 0.2, 0.45) for R in (0.03, 0.1, 0.3, 1.0)]
        else:
            k0 = float(self.structure.k_f)
            r0 = float(self.structure.restitution)
            grid = [{"k_f": k, "r": r, "beta": 0.3}
                    for k in (k0 / 3, k0, 3 * k0) for r in (0.5, r0, 0.9)]
        out, seen = [], set()
        for g in grid:
            z = self.to_z({**g, **self.fixed})
            key = tuple(np.round(z, 6))
            if key not in seen:
                seen.add(key)
                out.append(z)
        return out
