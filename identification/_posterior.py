r"""Posteriors by NUTS: `sample_posterior` and its result, `Posterior`.

Any fit that hands over a `PosteriorProblem` (`identification._bayes`; a decay fit's
`FitResult.posterior_problem`, `identification._posterior_decay`) is sampled here with the
No-U-Turn sampler of blackjax (`blackjax.nuts`, its step size and diagonal mass matrix
tuned during warmup as `blackjax.window_adaptation` does: Stan's windows, dual averaging
of the step size), several chains run together (`jax.vmap` over the chains, or one after
another and split over the CPU devices when the problem says so,
`PosteriorProblem.chains_together`: one compiled program, `_chunk`, for the warmup and the
draws, reused by any problem of the same shapes). Chains run one after another build
their trajectories in loops of static length (`_static_loops`): the same transitions,
with the gradient about 6 times cheaper on the CPU.

**Whitening.** The chains run in $w$, with $z = z^* + L w$ and $L L^T$ the fit's Laplace
covariance in $z$ (`PosteriorProblem.cov0`): where the Laplace approximation holds, the
posterior in $w$ is close to a standard normal and the adaptation starts from the right
scales (the mass matrix adapted on top of it). The chains start dispersed,
$w_0 = 2\,\mathcal N(0, I)$ (twice the Laplace spread), so that chains that do not meet
show in R-hat.

**Diagnostics** (`blackjax.diagnostics`): the rank-normalised split R-hat (Vehtari et al.
2021, the larger of the bulk and folded values) and the bulk effective sample size of each
parameter, the divergences after warmup, the mean acceptance rate and the step sizes. The
result is `ok` when every R-hat is at most `RHAT_MAX` = 1.01, every bulk ESS at least
`ESS_MIN` = 400 (100 per chain with fewer than 4 chains x 100 draws: see `ess_threshold`)
and no transition diverged; when it is not, a `PosteriorWarning` names what failed,
`Posterior.report()` starts with a warning line and `summary()["ok"]` is False.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._bayes import PosteriorProblem

RHAT_MAX = 1.01
"""The largest R-hat of a posterior that is `ok` (Vehtari et al. 2021)."""
ESS_MIN = 400
"""The smallest bulk ESS of a posterior that is `ok` (Vehtari et al. 2021: 100 per chain,
4 chains); with fewer draws in all, `ess_threshold` lowers it."""
TARGET_ACCEPTANCE = 0.8
"""The mean acceptance rate the step size is tuned to (dual averaging, during warmup)."""
MAX_DOUBLINGS = 10
"""The most trajectory doublings of a NUTS transition (blackjax's and Stan's default: at
most 2**10 - 1 leapfrog steps)."""
CHUNK = 25
"""Transitions per compiled call (warmup and draws: the progress bar's steps); the warmup
and the draws are rounded up to whole chunks (the extra draws are dropped)."""


class PosteriorWarning(UserWarning):
    """The posterior's diagnostics fail (R-hat above 1.01, a low effective sample size or
    divergent transitions): its draws do not describe the posterior."""


def ess_threshold(chains: int, draws: int) -> float:
    """The bulk ESS a posterior needs to be `ok`: `ESS_MIN` = 400, or 10 % of the draws
    when there are fewer than 4000 in all (a short run of few draws is judged on its mixing:
    100 effective draws of 1000 in all, say)."""
    return float(min(ESS_MIN, 0.1 * chains * draws))


def _problem_of(source, priors) -> PosteriorProblem:
    if isinstance(source, PosteriorProblem):
        if priors is not None:
            raise ValueError("priors: given with a PosteriorProblem, which holds its own "
                             "(make the problem with result.posterior_problem(priors))")
        return source
    make = getattr(source, "posterior_problem", None)
    if make is None:
        raise TypeError("sample_posterior: expected a PosteriorProblem or a fit result with "
                        f".posterior_problem(priors), got {type(source).__name__}")
    return make(priors)


def _check_counts(chains, draws, warmup):
    for name, v, low in (("chains", chains, 1), ("draws", draws, 4), ("warmup", warmup, 0)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {v!r}")


def _bar(total, enabled, desc):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="draw", file=sys.stderr, leave=False)


def sample_posterior(source, *, priors=None, chains: int = 4, draws: int = 1000,
                     warmup: int = 500, seed: int = 0, progress=None, init=None) -> Posterior:
    r"""Sample the posterior of a fit with NUTS (blackjax), `chains` chains run together.

    **Arguments:**

    - `source`: an `identification.PosteriorProblem`, or a fit result with
      `.posterior_problem(priors)` (a `FitResult` of `fit_decay`, say).
    - `priors`: None (the fit's documented defaults), or a dict name -> `Prior` or text
      ("lognormal(2e6, 1)"), passed to `source.posterior_problem`.
    - `chains`, `draws`, `warmup`: the chains, the draws kept per chain, and the warmup
      (adaptation of the step size and the diagonal mass matrix) per chain; both are
      rounded up to whole chunks of `CHUNK` = 25 transitions (the extra draws dropped).
    - `seed`: the random seed (`jax.random.key`).
    - `progress`: a tqdm bar on stderr (default None: when stderr is a terminal).
    - `init`: the starting points in the unconstrained coordinates z, shape
      (chains, d) (default: dispersed around the fit's optimum, see the module docstring).

    **Returns:** a `Posterior`. Warns `PosteriorWarning` when its diagnostics fail
    (`Posterior.ok` False; the warning names each failure).

    Example (minutes on a CPU: not run by the docstring tests):

    ```
    trace, truth = identification.synthetic_trace(duration=8.0, seed=3)
    fit = identification.fit_decay(trace, rockjax.mcmanus_column())
    post = identification.sample_posterior(fit)    # 4 chains x 1000 draws
    print(post.report())                           # WARNING first if the diagnostics fail
    post.interval("k_f", 0.9), post.ok
    post.to_csv("draws.csv")                       # for rockjax fragility --draws
    ```
    """
    from ._residuals import _checks_as_nan

    _check_counts(chains, draws, warmup)
    pb = _problem_of(source, priors)
    d = len(pb.names)
    z0 = jnp.asarray(np.asarray(pb.z0, float))
    cov0 = np.eye(d) if pb.cov0 is None else np.asarray(pb.cov0, float)
    L = _cholesky(cov0)
    Lj = jnp.asarray(L)

    key = jax.random.key(seed)
    k_init, k_warm, k_draw = jax.random.split(key, 3)
    if init is None:
        w_init = 2.0 * jax.random.normal(k_init, (chains, d))
    else:
        zi = np.asarray(init, float)
        if zi.shape != (chains, d):
            raise ValueError(f"init: shape {zi.shape}, expected (chains, d) = ({chains}, {d})")
        w_init = jnp.asarray(np.linalg.solve(L, (zi - np.asarray(z0)).T).T)
    show = progress if progress is not None else sys.stderr.isatty()
    t_start = time.perf_counter()
    with _checks_as_nan():
        w_draws, info, step_size, t_warm = _run(pb, Lj, k_warm, k_draw, w_init, warmup,
                                                draws, show)
    seconds = time.perf_counter() - t_start
    w_draws = np.asarray(w_draws)  # (chains, draws, d)
    z_draws = np.asarray(z0) + w_draws @ L.T
    phys = jax.jit(jax.vmap(pb.physical_vector))(jnp.asarray(z_draws.reshape(-1, d)))
    phys = np.asarray(phys).reshape(chains, draws, d)
    laplace = _laplace(pb, np.asarray(z0), cov0)
    return Posterior.build(
        pb, phys, z_draws, divergent=np.asarray(info["divergent"]),
        acceptance=np.asarray(info["acceptance"]), steps=np.asarray(info["steps"]),
        step_size=np.asarray(step_size), laplace=laplace,
        settings={"chains": chains, "draws": draws, "warmup": warmup, "seed": seed,
                  "likelihood": pb.likelihood_note},
        seconds={"warmup_s": t_warm, "total_s": seconds})


MAX_Z_SD = 3.0
"""The largest sd of a coordinate of z that the whitening takes from the Laplace covariance:
a parameter the fit cannot pin down (a k_f run off to the rigid limit, its standard error
1e30) would otherwise start the chains where the model overflows; its scale is then set by
the warmup (the mass matrix) instead."""


def _cholesky(cov: np.ndarray) -> np.ndarray:
    """A lower-triangular L with L L^T = cov (made positive definite if need be, and no
    coordinate's sd above `MAX_Z_SD`)."""
    cov = 0.5 * (cov + cov.T)
    if not np.all(np.isfinite(cov)):
        return np.eye(cov.shape[0])
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    shrink = np.where(sd > MAX_Z_SD, MAX_Z_SD / np.where(sd > 0, sd, 1.0), 1.0)
    cov = cov * np.outer(shrink, shrink)
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        vals, vecs = np.linalg.eigh(cov)
        floor = max(float(vals.max()), 1.0) * 1e-10
        return np.linalg.cholesky((vecs * np.maximum(vals, floor)) @ vecs.T)


def _windows(n: int) -> list:
    """The warmup's windows, in chunks (Stan's scheme): a first window that tunes the step
    size only (15 %), slow windows of doubling length that also estimate the mass matrix,
    and a last one for the step size (10 %); [(chunks, estimates the mass matrix)]."""
    if n < 4:
        return [(n, False)] if n else []
    first, last = max(1, round(0.15 * n)), max(1, round(0.1 * n))
    slow, size, out = n - first - last, 1, []
    while slow > 0:
        k = size if slow >= 3 * size else slow  # the last slow window takes the rest
        out.append((k, True))
        slow -= k
        size *= 2
    return [(first, False), *out, (last, False)]


def _log_density(spec, ll, tp, z0, L):
    """The log density of the whitened coordinates w (z = z0 + L w) of the problem made of
    `spec` (names, priors), `ll` (its log_likelihood) and `tp` (its to_physical)."""
    names, priors = spec
    pb = PosteriorProblem(names=names, log_likelihood=ll, to_physical=tp, z0=z0, cov0=None,
                          priors=dict(priors))
    return lambda w: pb.log_density(z0 + L @ w)


def _over_chains(f, together, *xs):
    """f over the leading (chain) axis of xs: `jax.vmap` when `together`, else
    `jax.lax.map` (one chain after the other; `PosteriorProblem.chains_together`), the
    chains split evenly over the devices when there are several (`rockjax.configure()`:
    one CPU device per core) and they divide the chains."""
    if together:
        return jax.vmap(f)(*xs)

    def serial(*xs):
        return jax.lax.map(lambda a: f(*a), xs)

    devices = jax.devices()
    chains = jax.tree.leaves(xs)[0].shape[0]
    if len(devices) < 2 or chains % len(devices):
        return serial(*xs)
    from jax.sharding import Mesh, PartitionSpec

    mesh = Mesh(np.array(devices), ("chains",))
    spec = PartitionSpec("chains")
    return jax.shard_map(serial, mesh=mesh, in_specs=(spec,) * len(xs), out_specs=spec,
                         check_vma=False)(*xs)


def _bounded_while(cond, body, init, n):
    """`jax.lax.while_loop(cond, body, init)` for a loop known to stop within `n` turns: a
    `lax.scan` of length n whose turns after the loop stops are a `lax.cond` that does
    nothing (about 40 ns each on the CPU)."""
    # as lax.while_loop does, weakly typed initial values take the body's dtypes
    shapes = jax.eval_shape(body, init)
    init = jax.tree.map(lambda x, o: jnp.asarray(x, o.dtype), init, shapes)

    def turn(c, _):
        return jax.lax.cond(cond(c), body, lambda c: c, c), None

    return jax.lax.scan(turn, init, None, length=n)[0]


class _TrajectoryLax:
    """`jax.lax` as blackjax's NUTS trajectory module sees it inside `_static_loops`: its
    two loops, which build the trajectory (`do_keep_integrating`: at most
    2**(MAX_DOUBLINGS - 1) leapfrog steps per doubling; `do_keep_expanding`: at most
    MAX_DOUBLINGS doublings), run as bounded scans (`_bounded_while`); anything else is
    `jax.lax`'s own."""

    BOUNDS = {"do_keep_integrating": 2 ** (MAX_DOUBLINGS - 1),
              "do_keep_expanding": MAX_DOUBLINGS}

    def __getattr__(self, name):
        return getattr(jax.lax, name)

    def while_loop(self, cond, body, init):
        n = self.BOUNDS.get(getattr(cond, "__name__", ""))
        if n is None:
            return jax.lax.while_loop(cond, body, init)
        return _bounded_while(cond, body, init, n)


class _TrajectoryJax:
    def __getattr__(self, name):
        return _TrajectoryLax() if name == "lax" else getattr(jax, name)


class _static_loops:
    """While tracing, NUTS's trajectory loops run as scans of static length
    (`_TrajectoryLax`): the same transitions, draw for draw, but XLA on the CPU runs a
    gradient about 6 times faster inside a loop of known length than inside a
    `lax.while_loop` whose length depends on the data (3.4 against 23 ms for the
    fixed-step decay likelihood; `benchmarks/posterior_time.md`). Only for chains run one
    after another: under `jax.vmap` a `lax.cond` computes both branches."""

    def __enter__(self):
        import blackjax.mcmc.trajectory as trajectory

        self._module, self._jax = trajectory, trajectory.jax
        trajectory.jax = _TrajectoryJax()
        return self

    def __exit__(self, *exc):
        self._module.jax = self._jax
        return False


@eqx.filter_jit
def _init(spec, ll, tp, z0, L, w_init, together=True):
    import blackjax

    logdensity = _log_density(spec, ll, tp, z0, L)
    return _over_chains(lambda w: blackjax.nuts.init(w, logdensity), together, w_init)


@eqx.filter_jit
def _chunk(spec, ll, tp, z0, L, states, das, imms, eps, keys, adapting, together=True):
    """`CHUNK` NUTS transitions of every chain (`jax.vmap` over them; keys (CHUNK,
    chains)); while `adapting`, the step size of each chain follows its dual averaging."""
    import blackjax
    from blackjax.adaptation.step_size import dual_averaging_adaptation

    logdensity = _log_density(spec, ll, tp, z0, L)
    _, da_update, _ = dual_averaging_adaptation(TARGET_ACCEPTANCE)

    def one(carry, k, imm, eps_fixed):
        state, da = carry
        eps = jnp.where(adapting, jnp.exp(da.log_step_size), eps_fixed)
        kernel = blackjax.nuts(logdensity, step_size=eps, inverse_mass_matrix=imm,
                               max_num_doublings=MAX_DOUBLINGS)
        state, info = kernel.step(k, state)
        acc = jnp.where(jnp.isfinite(info.acceptance_rate), info.acceptance_rate, 0.0)
        da_new = da_update(da, acc)
        da = jax.tree.map(lambda a, b: jnp.where(adapting, a, b), da_new, da)
        return (state, da), (state.position, info.is_divergent, acc,
                             info.num_integration_steps)

    def body(carry, ks):
        return _over_chains(one, together, carry, ks, imms, eps)

    if together:
        return jax.lax.scan(body, (states, das), keys)
    with _static_loops():
        return jax.lax.scan(body, (states, das), keys)


def _run(pb, L, k_warm, k_draw, w_init, warmup, draws, show):
    """Warmup, then `draws` NUTS transitions of every chain: one compiled program
    (`_chunk`: `CHUNK` transitions of all the chains, the step size tuned by dual averaging
    inside it while warming up), called chunk after chunk (the progress bar's steps); the
    diagonal mass matrix estimated between chunks, at the end of each slow window
    (`_windows`). The program takes the problem's arrays as arguments (an equinox module
    log-likelihood's leaves): a second problem of the same shapes reuses it. Returns
    positions (chains, draws, d), infos, step sizes and the warmup's seconds."""
    from blackjax.adaptation.step_size import dual_averaging_adaptation

    da_init, _, da_final = dual_averaging_adaptation(TARGET_ACCEPTANCE)
    chains, d = w_init.shape
    spec = (tuple(pb.names), tuple(sorted(pb.priors.items())))
    args = (spec, pb.log_likelihood, pb.to_physical, jnp.asarray(np.asarray(pb.z0, float)), L)
    together = bool(pb.chains_together)
    states = _init(*args, w_init, together)
    eps = jnp.full(chains, 0.5)
    das = jax.vmap(da_init)(eps)
    imms = jnp.ones((chains, d))
    yes, no = jnp.asarray(True), jnp.asarray(False)
    n_warm = -(-warmup // CHUNK)
    n_draw = -(-draws // CHUNK)
    wkeys = jax.random.split(k_warm, max(n_warm, 1) * CHUNK * chains).reshape(-1, CHUNK,
                                                                              chains)
    dkeys = jax.random.split(k_draw, n_draw * CHUNK * chains).reshape(-1, CHUNK, chains)
    bar = _bar((n_warm + n_draw) * CHUNK * chains, show, "posterior (warmup, draws)")
    t0 = time.perf_counter()
    try:
        c = 0
        for size, slow in _windows(n_warm):
            positions = []
            for _ in range(size):
                (states, das), o = _chunk(*args, states, das, imms, eps, wkeys[c], yes,
                                             together)
                c += 1
                positions.append(np.asarray(o[0]))
                if bar is not None:
                    bar.update(CHUNK * chains)
            eps = jax.vmap(da_final)(das)
            if slow:  # Stan's regularised variance of the window's positions
                x = np.concatenate(positions)  # (n, chains, d)
                n = x.shape[0]
                var = (n / (n + 5.0)) * np.var(x, axis=0) + 1e-3 * (5.0 / (n + 5.0))
                imms = jnp.asarray(var)
            das = jax.vmap(da_init)(eps)
        t_warm = time.perf_counter() - t0
        out = []
        for c in range(n_draw):
            (states, das), o = _chunk(*args, states, das, imms, eps, dkeys[c], no, together)
            out.append(jax.tree.map(np.asarray, o))
            if bar is not None:
                bar.update(CHUNK * chains)
    finally:
        if bar is not None:
            bar.close()
    pos, div, acc, steps = (np.concatenate([o[i] for o in out])[:draws] for i in range(4))

    def swap(x):  # (draws, chains, ...) -> (chains, draws, ...)
        return np.swapaxes(x, 0, 1)

    return (swap(pos), {"divergent": swap(div), "acceptance": swap(acc),
                        "steps": swap(steps)}, np.asarray(eps), t_warm)


def _laplace(pb: PosteriorProblem, z0: np.ndarray, cov0: np.ndarray) -> dict:
    """The Laplace approximation in physical units: value at z0 and the delta-method SE
    (J cov0 J^T, J = dx/dz at z0), and the covariance."""
    x0 = np.asarray(pb.physical_vector(jnp.asarray(z0)))
    J = np.asarray(jax.jacfwd(pb.physical_vector)(jnp.asarray(z0)))
    cov = J @ cov0 @ J.T
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return {"value": dict(zip(pb.names, map(float, x0))),
            "se": dict(zip(pb.names, map(float, se))), "cov": cov}


def diagnostics(x: np.ndarray) -> tuple[float, float]:
    """(rank-normalised split R-hat, bulk ESS) of draws `x` (chains, draws), by
    `blackjax.diagnostics.rhat` and `.ess_bulk` (Vehtari et al. 2021). A parameter that
    does not move (every draw equal) has R-hat nan, ESS 0 when its chains differ, and
    R-hat 1, ESS of all the draws when they do not."""
    import blackjax

    x = np.asarray(x, float)
    if np.ptp(x) == 0.0:
        return 1.0, float(x.size)
    if x.shape[0] < 2 and x.shape[1] < 8:
        return math.nan, math.nan
    rhat = float(blackjax.diagnostics.rhat(jnp.asarray(x)))
    ess = float(blackjax.diagnostics.ess_bulk(jnp.asarray(x)))
    return rhat, ess


@dataclasses.dataclass(frozen=True, eq=False)
class Posterior:
    """Draws of a posterior (`sample_posterior`) and their diagnostics.

    - `names`, `units`: the parameters (physical SI values) and their units.
    - `chains_draws`: dict name -> array (chains, draws) of physical values;
      `draws`: dict name -> the same flattened (chains x draws).
    - `z`: the draws in the unconstrained coordinates (chains, draws, d).
    - `rhat`, `ess`: rank-normalised split R-hat and bulk ESS per parameter.
    - `divergences`: divergent transitions after warmup; `acceptance`: the mean
      acceptance rate; `step_size`: per chain; `n_leapfrog`: the mean integration steps
      per draw.
    - `laplace`: the fit's Laplace approximation (`value`, `se` per parameter).
    - `ok`: R-hat <= `RHAT_MAX`, ESS >= `ess_threshold` and no divergence;
      `problems`: what failed, in words (empty when ok).
    - `priors`: name -> the prior, in words; `source`: the kind of fit; `settings`:
      chains, draws, warmup, seed and `likelihood` (how it was computed, when not by the
      fit's own solver: `PosteriorProblem.likelihood_note`); `seconds`: warmup and total
      wall time.
    """

    names: tuple
    units: dict
    chains_draws: dict
    z: np.ndarray
    rhat: dict
    ess: dict
    divergences: int
    acceptance: float
    step_size: np.ndarray
    n_leapfrog: float
    laplace: dict
    priors: dict
    source: str
    settings: dict
    seconds: dict
    problems: tuple

    @classmethod
    def build(cls, pb, phys, z, *, divergent, acceptance, steps, step_size, laplace,
              settings, seconds, warn=True) -> Posterior:
        chains, draws, _ = phys.shape
        cd = {n: phys[:, :, i] for i, n in enumerate(pb.names)}
        rh, es = {}, {}
        for n in pb.names:
            rh[n], es[n] = diagnostics(cd[n])
        need = ess_threshold(chains, draws)
        problems = []
        bad_r = {n: v for n, v in rh.items() if not v <= RHAT_MAX}
        if bad_r:
            problems.append(f"R-hat above {RHAT_MAX:.2f} (the chains disagree: a "
                            "multimodal posterior or chains that have not mixed): "
                            + ", ".join(f"{n} {v:.3g}" for n, v in bad_r.items()))
        bad_e = {n: v for n, v in es.items() if not v >= need}
        if bad_e:
            problems.append(f"bulk ESS below {need:.0f}: "
                            + ", ".join(f"{n} {v:.0f}" for n, v in bad_e.items()))
        n_div = int(np.sum(divergent))
        if n_div:
            problems.append(f"{n_div} divergent transitions (of {divergent.size}): the "
                            "sampler missed part of the posterior")
        post = cls(names=tuple(pb.names), units={n: pb.units.get(n, "") for n in pb.names},
                   chains_draws=cd, z=z, rhat=rh, ess=es, divergences=n_div,
                   acceptance=float(np.mean(acceptance)), step_size=np.asarray(step_size),
                   n_leapfrog=float(np.mean(steps)), laplace=laplace,
                   priors={n: pb.priors[n].describe() for n in pb.names}, source=pb.source,
                   settings=dict(settings), seconds=dict(seconds), problems=tuple(problems))
        if warn and problems:
            warnings.warn(post.warning_text(), PosteriorWarning, stacklevel=3)
        return post

    @property
    def ok(self) -> bool:
        """True when every diagnostic passes (`problems` empty)."""
        return not self.problems

    @property
    def draws(self) -> dict:
        """name -> all the draws (chains x draws), physical values."""
        return {n: v.reshape(-1) for n, v in self.chains_draws.items()}

    def warning_text(self) -> str:
        """The warning of a posterior whose diagnostics fail ("" when ok)."""
        if self.ok:
            return ""
        return ("WARNING: the posterior's diagnostics FAIL, do not use these draws as the "
                "posterior: " + "; ".join(self.problems)
                + ". Run more warmup and draws, or look at the trace plots (Posterior.plot)")

    def interval(self, name: str, level: float = 0.9) -> tuple[float, float]:
        """The central credible interval of `name` at `level` (quantiles of the draws)."""
        if name not in self.chains_draws:
            raise KeyError(f"{name!r}: not a parameter of this posterior ({', '.join(self.names)})")
        if not 0.0 < level < 1.0:
            raise ValueError(f"level must lie in (0, 1), got {level}")
        x = self.draws[name]
        lo, hi = np.quantile(x, [(1 - level) / 2, (1 + level) / 2])
        return float(lo), float(hi)

    def draws_dict(self, n: int | None = None, seed: int = 0) -> dict:
        """name -> 1-D array of physical draws (the contract of the predictions): all of
        them (n None), or n of them, evenly thinned when n <= the draws, else resampled
        with replacement (numpy `default_rng(seed)`); the same rows for every name."""
        total = next(iter(self.draws.values())).size
        if n is None:
            idx = np.arange(total)
        elif n <= 0:
            raise ValueError(f"n must be positive, got {n}")
        elif n <= total:
            idx = np.round(np.linspace(0, total - 1, n)).astype(int)
        else:
            idx = np.random.default_rng(seed).integers(0, total, n)
        return {k: np.asarray(v[idx], float) for k, v in self.draws.items()}

    def to_csv(self, path) -> None:
        """The draws as CSV: a first line `# units: k_f N/m, r -, ...`, a header of the plain
        names, one row per draw (chains one after the other)."""
        d = self.draws
        with open(path, "w", encoding="utf-8") as f:
            f.write("# units: " + ", ".join(f"{n} {self.units.get(n) or '-'}"
                                            for n in self.names) + "\n")
            f.write(",".join(self.names) + "\n")
            cols = np.column_stack([d[n] for n in self.names])
            for row in cols:
                f.write(",".join(repr(float(v)) for v in row) + "\n")

    def summary(self) -> dict:
        """JSON-ready: `ok`, `problems`, per parameter mean, sd, q05, q50, q95, R-hat, ESS
        and the Laplace value and SE; divergences, acceptance, step sizes, priors, units,
        settings, seconds."""
        params = {}
        for n in self.names:
            x = self.draws[n]
            q = np.quantile(x, [0.05, 0.5, 0.95])
            params[n] = {"mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)),
                         "q05": float(q[0]), "q50": float(q[1]), "q95": float(q[2]),
                         "rhat": self.rhat[n], "ess_bulk": self.ess[n],
                         "laplace_value": self.laplace["value"].get(n),
                         "laplace_se": self.laplace["se"].get(n)}
        return {"ok": self.ok, "problems": list(self.problems), "source": self.source,
                "sampler": "NUTS (blackjax), window adaptation", "parameters": params,
                "divergences": self.divergences, "acceptance_rate": self.acceptance,
                "step_size": [float(s) for s in self.step_size],
                "mean_leapfrog_steps": self.n_leapfrog, "priors": dict(self.priors),
                "units": dict(self.units), "settings": dict(self.settings),
                "seconds": dict(self.seconds)}

    def report(self) -> str:
        """The posterior as text: a WARNING line first when the diagnostics fail, then per
        parameter the mean, sd, 90 % interval, R-hat, ESS and the Laplace value +- SE; the
        divergences, acceptance and step sizes; the priors."""
        lines = [self.warning_text()] if not self.ok else []
        s = self.settings
        lines.append(f"posterior     NUTS, {s['chains']} chains x {s['draws']} draws "
                     f"(warmup {s['warmup']}), {self.seconds['total_s']:.1f} s; diagnostics "
                     + ("ok" if self.ok else "FAIL"))
        lines.append(f"{'parameter':<10} {'mean':>12} {'sd':>11} {'5 %':>12} {'95 %':>12} "
                     f"{'R-hat':>7} {'ESS':>6}   Laplace value +- SE")
        for n in self.names:
            x = self.draws[n]
            lo, hi = np.quantile(x, [0.05, 0.95])
            lines.append(f"{n:<10} {np.mean(x):>12.6g} {np.std(x, ddof=1):>11.4g} "
                         f"{lo:>12.6g} {hi:>12.6g} {self.rhat[n]:>7.4f} {self.ess[n]:>6.0f}   "
                         f"{self.laplace['value'][n]:.6g} +- {self.laplace['se'][n]:.4g} "
                         f"{self.units.get(n, '')}")
        lines.append(f"divergences   {self.divergences}; acceptance {self.acceptance:.2f}; "
                     "step size " + ", ".join(f"{v:.3g}" for v in self.step_size)
                     + f"; {self.n_leapfrog:.1f} leapfrog steps per draw")
        lines.append("priors        " + "; ".join(f"{n} {p}" for n, p in self.priors.items()))
        if s.get("likelihood"):
            lines.append("likelihood    " + s["likelihood"])
        return "\n".join(lines)

    def plot(self, pair=("k_f", "r"), fig=None):
        """Trace plots of every parameter (one line per chain) and a pair plot of `pair`
        (default k_f against r) with the Laplace 1- and 2-sigma ellipses beside the draws.
        Returns the matplotlib figure."""
        from ._posterior_plot import plot_posterior

        return plot_posterior(self, pair=pair, fig=fig)
