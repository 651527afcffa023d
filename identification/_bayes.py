r"""Priors and the posterior problem: what every kind of fit hands to the sampler.

A fit (of a decay trace, of a shake-table run, of topple outcomes) describes its posterior
as a `PosteriorProblem`: its log-likelihood as a JAX function of the fit's unconstrained
coordinates $z$ (the optimiser's, `identification._transforms`), the map $z \mapsto x$ to
the physical parameters, the optimum $z^*$ and its Laplace covariance, and a `Prior` per
physical parameter. The log density the sampler explores is

$$\log p(z \mid \text{data}) = \log L(z) + \sum_i \log \pi_i(x_i(z))
+ \log\left|\det \frac{\partial x}{\partial z}\right| + \text{const},$$

the priors stated on the physical parameters (k_f [N/m], r [-], ...), the Jacobian term
making them so in $z$.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

KINDS = ("flat", "uniform", "normal", "lognormal", "halfnormal")
"""The prior families: `flat` (improper, constant), `uniform(low, high)`, `normal(mean,
sd)`, `lognormal(median, sigma_ln)` (sigma_ln the sd of ln x) and `halfnormal(scale)`."""


@dataclasses.dataclass(frozen=True)
class Prior:
    """A prior on one physical parameter (its own SI unit).

    Make one with `Prior.flat()`, `Prior.uniform(low, high)`, `Prior.normal(mean, sd)`,
    `Prior.lognormal(median, sigma_ln)` or `Prior.halfnormal(scale)`, or from text with
    `parse_prior("lognormal(2e6, 1.0)")` (the CLI's `--prior k_f=lognormal(2e6,1)`).

    >>> identification.Prior.lognormal(2e6, 1.0).describe()
    'lognormal(median=2e+06, sigma_ln=1)'
    """

    kind: str
    a: float = 0.0
    b: float = 0.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"prior kind {self.kind!r}: expected one of {', '.join(KINDS)}")
        a, b = float(self.a), float(self.b)
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ValueError(f"prior {self.kind}: its numbers must be finite, got {a}, {b}")
        bad = {"uniform": not a < b, "normal": not b > 0, "lognormal": not (a > 0 and b > 0),
               "halfnormal": not a > 0}.get(self.kind, False)
        if bad:
            raise ValueError(f"prior {self.describe()}: "
                             + {"uniform": "needs low < high",
                                "normal": "needs sd > 0",
                                "lognormal": "needs median > 0 and sigma_ln > 0",
                                "halfnormal": "needs scale > 0"}[self.kind])

    @classmethod
    def flat(cls) -> Prior:
        """An improper constant prior (the likelihood alone)."""
        return cls("flat")

    @classmethod
    def uniform(cls, low: float, high: float) -> Prior:
        """Uniform on [low, high]."""
        return cls("uniform", low, high)

    @classmethod
    def normal(cls, mean: float, sd: float) -> Prior:
        """Normal with this mean and standard deviation."""
        return cls("normal", mean, sd)

    @classmethod
    def lognormal(cls, median: float, sigma_ln: float) -> Prior:
        """ln x normal, with median `median` and standard deviation `sigma_ln`."""
        return cls("lognormal", median, sigma_ln)

    @classmethod
    def halfnormal(cls, scale: float) -> Prior:
        """|N(0, scale)| on x ≥ 0."""
        return cls("halfnormal", scale)

    def log_pdf(self, x):
        """log π(x) up to a constant (JAX-traceable); -inf outside the support."""
        x = jnp.asarray(x)
        if self.kind == "flat":
            return jnp.zeros_like(x)
        if self.kind == "uniform":
            return jnp.where((x >= self.a) & (x <= self.b), 0.0, -jnp.inf)
        if self.kind == "normal":
            return -0.5 * ((x - self.a) / self.b) ** 2
        if self.kind == "halfnormal":
            return jnp.where(x >= 0, -0.5 * (x / self.a) ** 2, -jnp.inf)
        # lognormal
        safe = jnp.where(x > 0, x, 1.0)
        lp = -0.5 * ((jnp.log(safe) - math.log(self.a)) / self.b) ** 2 - jnp.log(safe)
        return jnp.where(x > 0, lp, -jnp.inf)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n draws (numpy); a flat prior has none (ValueError)."""
        if self.kind == "flat":
            raise ValueError("a flat prior cannot be sampled")
        return {"uniform": lambda: rng.uniform(self.a, self.b, n),
                "normal": lambda: rng.normal(self.a, self.b, n),
                "lognormal": lambda: self.a * np.exp(self.b * rng.standard_normal(n)),
                "halfnormal": lambda: np.abs(self.a * rng.standard_normal(n))}[self.kind]()

    def describe(self) -> str:
        """The prior in words, as `parse_prior` reads it."""
        names = {"flat": (), "uniform": ("low", "high"), "normal": ("mean", "sd"),
                 "lognormal": ("median", "sigma_ln"), "halfnormal": ("scale",)}[self.kind]
        vals = (self.a, self.b)[: len(names)]
        return f"{self.kind}(" + ", ".join(f"{n}={v:g}" for n, v in zip(names, vals)) + ")"


_PRIOR_RE = re.compile(r"^\s*([a-z]+)\s*\(([^)]*)\)\s*$")


def parse_prior(text: str) -> Prior:
    """A `Prior` from text: "lognormal(2e6, 1)", "uniform(0.5, 1)", "normal(0, 0.01)",
    "halfnormal(100)", "flat()" (or "flat"). ValueError naming the text otherwise.

    >>> identification.parse_prior("uniform(0.5, 1)")
    Prior(kind='uniform', a=0.5, b=1.0)
    """
    if isinstance(text, Prior):
        return text
    s = str(text).strip().lower()
    if s == "flat":
        return Prior.flat()
    m = _PRIOR_RE.match(s)
    if not m:
        raise ValueError(f"prior {text!r}: expected kind(numbers), e.g. 'lognormal(2e6, 1)'"
                         f" (kinds: {', '.join(KINDS)})")
    kind, body = m.group(1), m.group(2).strip()
    try:
        nums = [float(v) for v in body.split(",")] if body else []
    except ValueError:
        raise ValueError(f"prior {text!r}: its arguments must be numbers") from None
    need = {"flat": 0, "uniform": 2, "normal": 2, "lognormal": 2, "halfnormal": 1}.get(kind)
    if need is None:
        raise ValueError(f"prior {text!r}: unknown kind {kind!r} (kinds: {', '.join(KINDS)})")
    if len(nums) != need:
        raise ValueError(f"prior {text!r}: {kind} takes {need} numbers, got {len(nums)}")
    return Prior(kind, *nums)


def parse_priors(priors, names, defaults: dict) -> dict:
    """The prior of every name: `defaults` (name -> Prior), replaced by the user's
    `priors` (a dict name -> Prior or text, or "name=text" strings). ValueError naming an
    unknown parameter."""
    out = dict(defaults)
    if priors is None:
        return {n: out.get(n, Prior.flat()) for n in names}
    items = priors.items() if isinstance(priors, dict) else (
        tuple(p.split("=", 1)) if "=" in p else (p, None) for p in priors)
    for name, text in items:
        name = str(name).strip()
        if text is None:
            raise ValueError(f"prior {name!r}: expected name=kind(numbers)")
        if name not in names:
            raise ValueError(f"prior on {name!r}: not a parameter of this fit "
                             f"(the parameters: {', '.join(names)})")
        out[name] = parse_prior(text)
    return {n: out.get(n, Prior.flat()) for n in names}


@dataclasses.dataclass(frozen=True, eq=False)
class PosteriorProblem:
    """What a fit hands to the sampler (`identification.sample_posterior`).

    - `names`: the physical parameters, in the order of z.
    - `log_likelihood(z)`: log L of the unconstrained coordinates z (shape (d,)), up to a
      constant; JAX-traceable, differentiable with `jax.grad`, vmappable; -inf (or a very
      low finite value) where the model fails.
    - `to_physical(z)`: dict name -> physical value (JAX-traceable).
    - `z0`: the optimum (unconstrained); `cov0`: its Laplace covariance in z (or None).
    - `priors`: name -> `Prior` (on the physical value).
    - `units`: name -> SI unit; `source`: "decay", "shake table" or "outcomes".
    - `chains_together`: the sampler runs the chains as one vectorised program (`jax.vmap`,
      True) or one after the other inside it (`jax.lax.map`, False: for a likelihood whose
      cost grows with the batch under `vmap`, the fixed-step solver's).
    - `likelihood_note`: how the likelihood is computed, when it is not the fit's own
      (`Posterior.report` prints it).
    """

    names: tuple
    log_likelihood: Callable
    to_physical: Callable
    z0: np.ndarray
    cov0: np.ndarray | None
    priors: dict
    units: dict = dataclasses.field(default_factory=dict)
    source: str = ""
    chains_together: bool = True
    likelihood_note: str = ""

    def physical_vector(self, z):
        """The physical values as a vector, order `names`."""
        v = self.to_physical(z)
        return jnp.stack([jnp.asarray(v[n], float) for n in self.names])

    def log_prior(self, z):
        """Σ log π_i(x_i(z)) + log|det ∂x/∂z| (the priors made densities in z)."""
        x = self.physical_vector(z)
        lp = sum(self.priors[n].log_pdf(x[i]) for i, n in enumerate(self.names))
        J = jax.jacfwd(self.physical_vector)(z)
        return lp + jnp.linalg.slogdet(J)[1]

    def log_density(self, z):
        """The log posterior density of z (up to a constant); -inf where it is not finite."""
        lp = self.log_likelihood(z) + self.log_prior(z)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)
