r"""The posterior of a fit of response channels (`FitResult.posterior_problem` of a decay,
`ShakeTableFitResult.posterior_problem` of a shake-table run): what the fit hands to the
sampler (`identification.sample_posterior`). Both kinds share this likelihood, its
gradient and its default priors.

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

**The fixed-step likelihood.** The fit's adaptive solver (diffrax, rtol 1e-9) costs about
25 ms a gradient for an 8-s trace, and under `jax.vmap` over the chains its loops run to the
longest member. The posterior therefore evaluates the same likelihood on the fixed-step
path (`TraceModel.on_grid`: `rockjax.integrators.RK4` steps of the trace's sample step,
events located inside each step, the response interpolated to the sample times), the chains
one after the other (`PosteriorProblem.chains_together` False), and only after checking it:
on `GRID_CHECK_POINTS` points of the Laplace approximation spread 1.5 times wider, the two
log likelihoods must differ by a constant to within a standard deviation of
`GRID_LOGL_SD` = 0.05 (the two posteriors then differ by about that much in total
variation: far inside the Monte Carlo error of the draws). A step that fails is halved, up
to `GRID_HALVINGS` times; if none passes, the posterior keeps the adaptive solver. The check
must also be able to fail: when the fit leaves a parameter unpinned (a Laplace sd above
`identification._posterior.MAX_Z_SD` in z: k_f run off to the rigid limit, say) or the
adaptive log L varies by less than `GRID_LOGL_SPREAD` over the points, the adaptive solver
is kept.
`PosteriorProblem.likelihood_note` (and `Posterior.report`) says which was used and the
measured difference.

**Default priors** (on the physical values; `DEFAULT_PRIORS`): k_f and c_f lognormal
around their starting values (the structure's k_f, the default or given c_f) with
$\sigma_{\ln} = 2$ (a factor of $e^2 \approx 7.4$ at one sd: weakly informative, not
centred on the fit), r uniform(0, 1), u0, t0 and the sensor's offsets and drift flat.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._bayes import parse_priors, PosteriorProblem, Prior
from ._problem import Problem, UNITS
from ._residuals import _checks_as_nan, TraceModel

GRID_CHECK_POINTS = 16
"""Points of the check of the fixed-step likelihood (module docstring)."""
GRID_LOGL_SD = 0.05
"""The largest sd of (fixed-step - adaptive) log L over those points."""
GRID_HALVINGS = 2
"""Halvings of the fixed step tried before keeping the adaptive solver."""
GRID_LOGL_SPREAD = 1.0
"""The smallest sd of the adaptive log L over the check's points: below it the points do not
probe the likelihood (a degenerate fit) and the check proves nothing."""

SIGMA_LN = 2.0
"""The sd of ln k_f (and ln c_f) of the default lognormal priors."""


def default_priors(params, values0) -> dict:
    """The default prior of every fitted parameter (module docstring; `values0`: the fit's
    starting values)."""
    out = {}
    for p in params:
        if p in ("k_f", "c_f"):
            out[p] = Prior.lognormal(float(values0[p]), SIGMA_LN)
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

    model: TraceModel  # or a joint fit's `_joint._JointModel`: the same two methods
    mask: jax.Array
    n_keep: jax.Array  # samples kept per group (one noise level each), or one count
    n_ch: int = eqx.field(static=True)  # groups: channels (x traces of a joint fit)

    def residuals(self, z):
        dyn, static = eqx.partition((self.model, self.mask), eqx.is_array)
        return _residuals(z, dyn, static)

    def __call__(self, z):
        r = self.residuals(z).reshape(self.n_ch, -1)
        rss = jnp.maximum(jnp.sum(r**2, axis=1), 1e-300)
        return -0.5 * jnp.sum(self.n_keep * jnp.log(rss))


class _ToPhysical(eqx.Module):
    model: TraceModel
    names: tuple = eqx.field(static=True)

    def __call__(self, z):
        v = self.model.decode(z)
        return {p: v[p] for p in self.names}


def decay_problem(problem: Problem, z_opt, keep, priors=None) -> PosteriorProblem:
    """The `PosteriorProblem` of a decay fit (module docstring): the fit's `Problem`, its
    optimum `z_opt` and the samples it kept (`keep`, bool per sample)."""
    return residual_problem(TraceModel.build(problem), keep, z_opt, priors, "decay")


def residual_problem(model: TraceModel, keep, z_opt, priors=None,
                     source: str = "decay") -> PosteriorProblem:
    """The `PosteriorProblem` of a fit of response channels (a decay, a shake-table run):
    its `TraceModel`, the samples it kept (`keep`, per sample), its optimum `z_opt`;
    each channel's noise level integrated out (Jeffreys), the default priors of
    `default_priors` under `priors` (module docstring)."""
    names = tuple(model.params)
    n_ch = sum(x is not None for x in (model.u, model.th, model.up))
    keep = np.asarray(keep) > 0
    return _problem(model, keep, np.full(n_ch, float(np.count_nonzero(keep))), z_opt,
                    names, default_priors(names, model.values0), priors,
                    _ToPhysical(model=model, names=names), source)


def joint_problem(model, keep, z_opt, names, values0, priors=None) -> PosteriorProblem:
    """The `PosteriorProblem` of a joint fit of several traces (`JointFitResult`):
    `model` its `_joint._JointModel` (residuals trace after trace, each trace's channels
    in turn), `keep` (traces, samples) the samples of each trace (not the padding),
    `names` the joint parameters (k_f, r shared; u0[i], t0[i] per trace), `values0`
    the starting values. A noise level per trace and channel, integrated out; the shared
    parameters' default priors as a single trace's, each trace's own flat."""
    keep = np.asarray(keep) > 0
    m = keep.shape[0]
    st = model.stacked
    n_ch = sum(x is not None for x in (st.u, st.th, st.up))
    n_keep = np.repeat(np.count_nonzero(keep, axis=1).astype(float), n_ch)
    return _problem(model, keep.reshape(-1), n_keep, z_opt, tuple(names),
                    default_priors(names, values0), priors,
                    _JointToPhysical(model=model, names=tuple(names), traces=m), "joint decay")


def _problem(model, keep, n_keep, z_opt, names, defaults, priors, to_physical, source):
    pri = parse_priors(priors, names, defaults)
    mask = jnp.asarray(keep, float)
    groups = n_keep.size
    log_likelihood = DecayLogLikelihood(model=model, mask=mask, n_keep=jnp.asarray(n_keep),
                                        n_ch=groups)
    z0 = np.asarray(z_opt, float)
    with _checks_as_nan():
        r0, J0 = eqx.filter_jit(lambda m, z, mk: m.res_jac(z, mk))(model, jnp.asarray(z0), mask)
    r0, J0 = np.asarray(r0).reshape(groups, -1), np.asarray(J0).reshape(groups, -1, z0.size)
    H = np.zeros((len(names),) * 2)
    for c in range(groups):
        rss = max(float(np.sum(r0[c] ** 2)), 1e-300)
        H += (n_keep[c] / rss) * (J0[c].T @ J0[c])
    try:
        cov0 = np.linalg.inv(H)
        if not np.all(np.isfinite(cov0)):
            cov0 = None
    except np.linalg.LinAlgError:
        cov0 = None
    fast, note = (None, "") if not isinstance(model, TraceModel) else _on_grid(
        log_likelihood, z0, cov0)
    return PosteriorProblem(names=names,
                            log_likelihood=log_likelihood if fast is None else fast,
                            to_physical=to_physical, z0=z0, cov0=cov0, priors=pri,
                            units={p: UNITS[p.split("[")[0]] for p in names}, source=source,
                            chains_together=fast is None, likelihood_note=note)


class _JointToPhysical(eqx.Module):
    model: object  # _joint._JointModel
    names: tuple = eqx.field(static=True)
    traces: int = eqx.field(static=True)

    def __call__(self, z):
        v = jax.vmap(lambda mod, zl: mod.decode(zl))(self.model.stacked, z[self.model.index])
        out = {}
        for p in self.names:
            base, _, i = p.partition("[")
            out[p] = v[base][int(i[:-1]) if i else 0]
        return out


def _on_grid(ll: DecayLogLikelihood, z0, cov0):
    """(the fixed-step log likelihood, or None, and the note): module docstring."""
    from ._posterior import MAX_Z_SD

    model = ll.model
    if cov0 is None or model.accel is not None:
        return None, ""
    if np.any(np.sqrt(np.maximum(np.diag(cov0), 0.0)) > MAX_Z_SD):
        # a parameter the fit does not pin down (k_f run off to the rigid limit, say): the
        # chains go where no check point lies
        return None, ("adaptive solver (the fit does not pin every parameter down: the "
                      "fixed-step likelihood cannot be checked where the chains go)")
    t = np.asarray(model.t, float)
    t0 = float(model.decode(jnp.asarray(z0))["t0"])
    span = float(t[-1]) - min(t0, float(t[0]))
    t1 = span + max(0.25, 0.02 * span)
    step = float(np.median(np.diff(t)))
    L = np.linalg.cholesky(cov0)
    w = 1.5 * np.random.default_rng(0).standard_normal((GRID_CHECK_POINTS, z0.size))
    Z = jnp.asarray(z0 + w @ L.T)
    values = eqx.filter_jit(lambda f, Z: jax.lax.map(f, Z))
    with _checks_as_nan():
        exact = np.asarray(values(ll, Z))
    ok = np.isfinite(exact)
    if np.count_nonzero(ok) < GRID_CHECK_POINTS // 2:
        return None, ""
    if float(np.std(exact[ok])) < GRID_LOGL_SPREAD:
        return None, ("adaptive solver (the check's points do not probe the likelihood: "
                      f"its log L varies by sd {float(np.std(exact[ok])):.2g} over them)")
    tried = []
    for k in range(GRID_HALVINGS + 1):
        dt = step / 2**k
        fast = dataclasses.replace(ll, model=model.on_grid(dt, t1))
        with _checks_as_nan():
            got = np.asarray(values(fast, Z))
        diff = got[ok] - exact[ok]
        sd = float(np.std(diff)) if np.all(np.isfinite(diff)) else math.inf
        tried.append(f"{1e3 * dt:.3g} ms: {sd:.2g}")
        if sd <= GRID_LOGL_SD:
            return fast, (f"fixed-step likelihood (RK4, dt {1e3 * dt:.3g} ms; its log L "
                          f"differs from the adaptive solver's by a constant to sd {sd:.2g} "
                          f"over {np.count_nonzero(ok)} Laplace points)")
    return None, ("adaptive solver (the fixed-step likelihood missed sd <= "
                  f"{GRID_LOGL_SD:g}: {'; '.join(tried)})")


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
