r"""The posterior of a decay fit (`FitResult.posterior_problem`): what `fit_decay` hands to
the sampler (`identification.sample_posterior`).

**Likelihood.** The residuals of each channel $c$ (u, theta, uplift; `TraceModel`: the
fit's own, in units of the trace amplitude, over the samples the fit kept) are independent
Gaussian noise of an unknown level $\sigma_c$. With the Jeffreys prior
$\pi(\sigma_c) \propto 1/\sigma_c$ the noise levels are integrated out exactly:

$$\log L(z) = -\sum_c \frac{n_c}{2} \log \mathrm{RSS}_c(z) + \text{const},$$

($n_c$ samples, $\mathrm{RSS}_c$ the channel's residual sum of squares): a Student-t form.
Marginalising rather than sampling $\log\sigma_c$ keeps the sampled dimension that of the
fit (the noise levels are well determined by the thousands of samples of a trace, and
add nothing but cost to the chains) and needs no prior on a scale the user rarely knows.

**Gradients.** The residuals go through the event-restart solver, differentiated in
forward mode (`TraceModel.res_jac`, `jax.jacfwd` with diffrax's `adjoint="forward"`).
`residuals` here is a `jax.custom_vjp` whose forward pass computes the residuals and that
Jacobian $J$ together and whose backward pass is $g \mapsto J^T g$: `jax.grad` of the log
likelihood (what NUTS takes at every leapfrog step) costs one forward-mode sweep with $d$
tangents and no reverse pass through the solver.

**Default priors** (on the physical values; `DEFAULT_PRIORS`): k_f and c_f lognormal
around their starting values (the structure's k_f, the default or given c_f) with
$\sigma_{\ln} = 2$ (a factor of $e^2 \approx 7.4$ at one sd: weakly informative, not
centred on the fit), r uniform(0, 1), u0, t0 and the sensor's offsets and drift flat.
"""

from __future__ import annotations

import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._bayes import parse_priors, PosteriorProblem, Prior
from ._problem import Problem, UNITS
from ._residuals import _checks_as_nan, TraceModel

SIGMA_LN = 2.0
"""The sd of ln k_f (and ln c_f) of the default lognormal priors."""


def default_priors(problem: Problem) -> dict:
    """The default prior of every fitted parameter (module docstring)."""
    out = {}
    for p in problem.params:
        if p in ("k_f", "c_f"):
            out[p] = Prior.lognormal(float(problem.values0[p]), SIGMA_LN)
        elif p == "r":
            out[p] = Prior.uniform(0.0, 1.0)
        else:
            out[p] = Prior.flat()
    return out


DEFAULT_PRIORS = ("k_f: lognormal(start, 2); c_f: lognormal(start, 2); r: uniform(0, 1); "
                  "u0, t0, offset, offset_uplift, offset_theta, drift: flat; each channel's "
                  "noise sigma: Jeffreys (1/sigma), integrated out")
"""The default priors of a decay fit's posterior, in words."""


@functools.partial(jax.custom_vjp, nondiff_argnums=(2,))
def _residuals(z, dyn, static):
    model, mask = eqx.combine(dyn, static)
    return model.residuals(z, mask)


def _residuals_fwd(z, dyn, static):
    model, mask = eqx.combine(dyn, static)
    r, J = model.res_jac(z, mask)
    return r, (J, dyn)


def _residuals_bwd(static, res, g):
    J, dyn = res
    return J.T @ g, jax.tree.map(jnp.zeros_like, dyn)


_residuals.defvjp(_residuals_fwd, _residuals_bwd)


class DecayLogLikelihood(eqx.Module):
    """log L(z) of a decay fit (module docstring): the residuals of each channel with its
    noise level integrated out. An equinox module (the trace's arrays are leaves), so that
    the sampler's compiled program is reused by any trace of the same length and settings;
    its gradient is J^T g with J the forward-mode Jacobian (`_residuals`, a custom VJP)."""

    model: TraceModel
    mask: jax.Array
    n_keep: jax.Array
    n_ch: int = eqx.field(static=True)

    def residuals(self, z):
        dyn, static = eqx.partition((self.model, self.mask), eqx.is_array)
        return _residuals(z, dyn, static)

    def __call__(self, z):
        r = self.residuals(z).reshape(self.n_ch, -1)
        rss = jnp.maximum(jnp.sum(r**2, axis=1), 1e-300)
        return -0.5 * self.n_keep * jnp.sum(jnp.log(rss))


class _ToPhysical(eqx.Module):
    model: TraceModel
    names: tuple = eqx.field(static=True)

    def __call__(self, z):
        v = self.model.decode(z)
        return {p: v[p] for p in self.names}


def decay_problem(problem: Problem, z_opt, keep, priors=None) -> PosteriorProblem:
    """The `PosteriorProblem` of a decay fit (module docstring): the fit's `Problem`, its
    optimum `z_opt` and the samples it kept (`keep`, bool per sample)."""
    model = TraceModel.build(problem)
    names = tuple(problem.params)
    pri = parse_priors(priors, names, default_priors(problem))
    keep = np.asarray(keep, bool)
    mask = jnp.asarray(keep, float)
    n_ch = len(problem.channels)
    log_likelihood = DecayLogLikelihood(model=model, mask=mask,
                                        n_keep=jnp.asarray(float(np.count_nonzero(keep))),
                                        n_ch=n_ch)
    to_physical = _ToPhysical(model=model, names=names)
    n = problem.t.size
    z0 = np.asarray(z_opt, float)
    with _checks_as_nan():
        r0, J0 = eqx.filter_jit(lambda m, z, mk: m.res_jac(z, mk))(model, jnp.asarray(z0), mask)
    r0, J0 = np.asarray(r0).reshape(n_ch, n), np.asarray(J0).reshape(n_ch, n, -1)
    H = np.zeros((len(names),) * 2)
    n_keep = float(np.count_nonzero(keep))
    for c in range(n_ch):
        rss = max(float(np.sum(r0[c] ** 2)), 1e-300)
        H += (n_keep / rss) * (J0[c].T @ J0[c])
    try:
        cov0 = np.linalg.inv(H)
        if not np.all(np.isfinite(cov0)):
            cov0 = None
    except np.linalg.LinAlgError:
        cov0 = None
    return PosteriorProblem(names=names, log_likelihood=log_likelihood,
                            to_physical=to_physical, z0=z0, cov0=cov0, priors=pri,
                            units={p: UNITS[p] for p in names}, source="decay")


def laplace_check(post, tol_mean: float = 0.5, tol_sd: float = 0.3) -> dict:
    """Where the Laplace approximation holds: for each parameter, |mean - value| / SE and
    sd / SE - 1 of a `Posterior` of a decay fit, and whether both are within `tol_mean`,
    `tol_sd`."""
    out = {}
    for p in post.names:
        se = post.laplace["se"][p]
        x = post.draws[p]
        dm = abs(float(np.mean(x)) - post.laplace["value"][p]) / se if se > 0 else math.inf
        ds = float(np.std(x, ddof=1)) / se - 1.0 if se > 0 else math.inf
        out[p] = {"mean_shift_se": dm, "sd_ratio_minus_1": ds,
                  "agrees": bool(dm <= tol_mean and abs(ds) <= tol_sd)}
    return out
