r"""Joint fit of several decay traces of one structure: shared $k_f$, $r$ (or $c_f$), and
a release $u_0$, $t_0$ of each trace.

`fit_decay([trace_1, trace_2, ...], structure)` lands here. Each trace is checked and its
release found as for a single fit (`_problem.setup`); the traces are padded to the length of
the longest (padded samples are masked out of the residuals: they never count), and the
model of every trace is evaluated at once, `jax.vmap` over the traces, with the single
fit's residuals and forward-mode Jacobian (`_residuals.TraceModel`). The unknowns are

$$z = (z_{shared},\ u_{0,1}, t_{0,1},\ u_{0,2}, t_{0,2},\ \dots)$$

in the single fit's coordinates; each trace's Jacobian (residuals x its own parameters) is
scattered into the joint one. The optimiser, the growing horizons, the multi-start and the
convergence test are those of the single fit (`_stages.run_stages`); the compiled step
depends only on the number of traces, the padded length and the static settings, so a
second joint fit of as many traces of that length reuses it.

Standard errors: the Gauss-Newton sandwich of the single fit, with a noise variance per
trace and channel (traces may have different noise). Not done in a joint fit: the outlier
pass (fit the traces one by one to find spikes). The lack-of-fit check is done per trace.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import _lack, _models, _sensor
from ._problem import as_trace, check_structure, NUISANCE, PARAM_NAMES, Settings, setup, UNITS
from ._residuals import compiled, response_structure, TraceModel
from ._result import LackOfFitWarning
from ._stages import best_start, optimizer_of, run_stages
from ._transforms import Transform

SHARED = ("k_f", "r", "c_f")
"""The parameters a joint fit shares between the traces (of one structure)."""
PER_TRACE = ("u0", "t0")
"""The parameters of each trace's release."""
OWN = PER_TRACE + NUISANCE
"""The parameters of each trace: its release, and its sensor's offsets and drift."""


@dataclasses.dataclass(frozen=True, eq=False)
class JointFitResult:
    """Result of `fit_decay` on several traces (SI units: k_f [N/m], r [-], c_f [N s/m],
    u0 [m], t0 [s]).

    - `names`, `values`, `stderr`, `fixed`, `start`: the shared parameters (fitted, held,
      starting values), as in `FitResult`.
    - `per_trace`: one dict per trace (in the order given): `source`, `n_points`,
      `values` / `stderr` of its fitted u0, t0, `fixed` (its held u0, t0), `rms` and
      `sigma` [m] (RMS displacement residual and noise estimate), `release` and
      `lack_of_fit` (as in `FitResult`).
    - `joint_names`, `correlation`: every fitted parameter (`u0[1]` for trace 1's u0) and
      their correlation matrix.
    - `responses`: the fitted `rockjax.Response` of each trace, on its own samples.
    - `loss` (all traces), `loss_history`, `start_losses`, `converged`, `n_iterations`,
      `warnings`, `model`, `notes`: as in `FitResult`.
    """

    names: tuple
    values: dict
    stderr: dict
    fixed: dict
    start: dict
    per_trace: tuple
    joint_names: tuple
    correlation: np.ndarray
    responses: tuple
    loss: float
    loss_history: np.ndarray
    start_losses: np.ndarray
    converged: bool
    n_iterations: int
    warnings: tuple
    model: str
    notes: tuple = ()
    #: what `posterior_problem` needs: (the joint model, its samples, the optimum z, the
    #: starting values)
    fit_state: tuple | None = dataclasses.field(default=None, repr=False, compare=False)

    def posterior_problem(self, priors=None):
        """The joint fit's posterior as an `identification.PosteriorProblem` (for
        `identification.sample_posterior`) over every fitted parameter (`joint_names`:
        k_f, r shared, `u0[i]`, `t0[i]` of each trace): each trace's noise level
        integrated out (Jeffreys prior), the shared parameters' default priors as a single
        trace's, each trace's own flat; `priors`: name -> `Prior` or text over them
        (`identification._posterior_decay.joint_problem`)."""
        from ._posterior_decay import joint_problem

        if self.fit_state is None:
            raise ValueError("this JointFitResult holds no fit state (made by hand, or by "
                             "an older version): fit the traces again with fit_decay")
        model, keep, z, values0 = self.fit_state
        return joint_problem(model, keep, z, self.joint_names, values0, priors)

    @property
    def n_traces(self) -> int:
        return len(self.per_trace)

    def report(self, read_warnings=()) -> str:
        """The joint fit as text (what `rockjax fit A.csv B.csv` prints): the shared values
        with their standard errors, each trace's u0, t0, rms residual and lack of fit, then
        `read_warnings`, the k_f correlations, loss, convergence, notes and warnings."""
        from ._report import joint_report

        return joint_report(self, read_warnings)

    def summary(self) -> dict:
        """A JSON-ready dict: the shared values, standard errors, held and starting
        values, `traces` (the per-trace dicts), the correlation of every fitted parameter,
        loss, converged, warnings, the model fitted (`fitted_model`), notes and `units`."""
        return {
            "units": {**UNITS, "rms": "m", "sigma": "m", "loss": "-"},
            "joint": True,
            "values": dict(self.values),
            "stderr": dict(self.stderr),
            "fixed": dict(self.fixed),
            "start": dict(self.start),
            "traces": [dict(p) for p in self.per_trace],
            "correlation": {
                a: {b: float(self.correlation[i, j]) for j, b in enumerate(self.joint_names)}
                for i, a in enumerate(self.joint_names)
            },
            "loss": self.loss,
            "converged": self.converged,
            "n_iterations": self.n_iterations,
            "warnings": list(self.warnings),
            "fitted_model": self.model,
            "notes": list(self.notes),
        }


# ------------------------------------------------------------------- the problem


def _check_traces(traces) -> list:
    traces = list(traces)
    if not traces:
        raise ValueError("trace: an empty list; give one DecayTrace, or a list of them for "
                         "a joint fit")
    out = []
    for i, tr in enumerate(traces):
        try:
            out.append(as_trace(tr))
        except ValueError as e:
            raise ValueError(f"trace[{i}]: {e}") from None
    return out


def _check_structures(structure, n: int):
    """The one structure of a joint fit (a list of them must hold one structure)."""
    if not isinstance(structure, (list, tuple)):
        return structure
    if len(structure) != n:
        raise ValueError(f"structure: {len(structure)} structures for {n} traces; a joint "
                         "fit is of one structure (give it once)")
    first = check_structure(structure[0])
    leaves0 = jax.tree.leaves(first)
    for i, s in enumerate(structure[1:], 1):
        leaves = jax.tree.leaves(check_structure(s))
        if len(leaves) != len(leaves0) or not all(
                np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(leaves, leaves0)):
            raise ValueError(
                f"structure: trace[{i}]'s structure differs from trace[0]'s; a joint fit "
                "shares k_f and r between traces of one structure (fit the others apart)")
    return first


@dataclasses.dataclass(frozen=True, eq=False)
class _JointProblem:
    """The traces' problems (`_problem.Problem`), padded to `n` samples, as one problem for
    `_stages.run_stages` (the attributes it reads)."""

    problems: tuple  # one Problem per trace (its own samples)
    n: int  # padded length
    params: tuple  # joint names: shared, then u0[i], t0[i]
    local: tuple  # the parameters of one trace (order of its z)
    index: np.ndarray  # (M, len(local)): joint index of each local parameter

    def __getattr__(self, name):  # starts, horizons, max_iter, tol, fit_model, progress
        return getattr(self.problems[0], name)

    @property
    def t(self) -> np.ndarray:  # only its size is read: the flat mask's
        return np.zeros(len(self.problems) * self.n)

    def samples(self) -> np.ndarray:
        """The samples of the traces, not the padding (flat, M * n)."""
        out = np.zeros((len(self.problems), self.n), bool)
        for i, pb in enumerate(self.problems):
            out[i, :pb.t.size] = True
        return out.reshape(-1)

    def within(self, frac: float) -> np.ndarray:
        """The samples of each trace's first `frac` of motion, padded (flat, M * n)."""
        out = np.zeros((len(self.problems), self.n), bool)
        for i, pb in enumerate(self.problems):
            out[i, :pb.t.size] = pb.within(frac)
        return out.reshape(-1)


def _joint_problem(traces, structure, params, settings: Settings) -> _JointProblem:
    problems = tuple(setup(tr, structure, params, settings) for tr in traces)
    if any(pb.channels[0] != "u" or pb.fits_theta for pb in problems):
        raise ValueError("a joint fit takes traces of u (and uplift): fit a trace with a "
                         "rotation channel, or without u, on its own")
    if len({pb.params for pb in problems}) > 1:  # the offset pinned in some traces only
        settings = dataclasses.replace(settings, offset=True)
        problems = tuple(setup(tr, structure, params, settings) for tr in traces)
    return joint_of(problems)


def joint_of(problems) -> _JointProblem:
    """The joint problem of the checked problems of each trace (or shake-table run:
    `identification._shakefit`): the same channels in each, k_f, r, c_f shared."""
    problems = tuple(problems)
    for i, pb in enumerate(problems[1:], 1):
        if pb.fits_uplift != problems[0].fits_uplift:
            has = "has" if pb.fits_uplift else "has no"
            raise ValueError(
                f"trace[{i}] {has} uplift channel, unlike trace[0]: a joint fit needs the "
                "same channels in every trace (drop the uplift, or set weights={'uplift': 0})")
    for i, pb in enumerate(problems[1:], 1):
        if pb.channels != problems[0].channels or pb.params != problems[0].params:
            raise ValueError(f"trace[{i}] has the channels {pb.channels} and the parameters "
                             f"{pb.params}, trace[0] {problems[0].channels} and "
                             f"{problems[0].params}: a joint fit needs the same in each")
    local = problems[0].params
    shared = [p for p in local if p in SHARED]
    own = [p for p in local if p in OWN]
    names = shared + [f"{p}[{i}]" for i in range(len(problems)) for p in own]
    index = np.array([[names.index(p if p in SHARED else f"{p}[{i}]") for p in local]
                      for i in range(len(problems))])
    return _JointProblem(problems=problems, n=max(pb.t.size for pb in problems),
                         params=tuple(names), local=local, index=index)


def _padded(pb, n: int):
    """The problem with its samples padded to `n` (times continue at its step)."""
    k = n - pb.t.size
    if k == 0:
        return pb
    dt = float(np.median(np.diff(pb.t)))
    t = np.concatenate([pb.t, pb.t[-1] + dt * np.arange(1, k + 1)])
    def pad(x):
        return None if x is None else np.pad(x, (0, k), mode="edge")

    return dataclasses.replace(pb, t=t, u_meas=pad(pb.u_meas), up_meas=pad(pb.up_meas),
                               th_meas=pad(pb.th_meas))


# ---------------------------------------------------------------------- the model


class _JointModel(eqx.Module):
    """The traces' models (`TraceModel`, array leaves stacked over the traces) and the
    map of each trace's parameters into the joint z."""

    stacked: TraceModel
    index: jax.Array  # (M, P_local) int
    scatter: jax.Array  # (M, P_local, P_joint) one-hot

    @classmethod
    def build(cls, jp: _JointProblem) -> _JointModel:
        models = [TraceModel.build(_padded(pb, jp.n)) for pb in jp.problems]
        arrays = [eqx.filter(m, eqx.is_array) for m in models]
        static = eqx.filter(models[0], eqx.is_array, inverse=True)
        stacked = eqx.combine(jax.tree.map(lambda *xs: jnp.stack(xs), *arrays), static)
        scatter = np.zeros(jp.index.shape + (len(jp.params),))
        for i, row in enumerate(jp.index):
            scatter[i, np.arange(row.size), row] = 1.0
        return cls(stacked=stacked, index=jnp.asarray(jp.index), scatter=jnp.asarray(scatter))

    def res_jac(self, z, mask):
        """Residuals of every trace (flat, trace after trace) and their Jacobian d r / d z
        (flat rows x joint parameters). `mask`: flat (M * n)."""
        m = self.index.shape[0]
        r, J = jax.vmap(lambda mod, zl, mk: mod.res_jac(zl, mk))(
            self.stacked, z[self.index], mask.reshape(m, -1))
        J = jnp.einsum("inp,ipq->inq", J, self.scatter)
        return r.reshape(-1), J.reshape(-1, J.shape[-1])

    def residuals(self, z, mask):
        """The residuals of every trace (flat, trace after trace; `mask` flat, M * n): what
        an optimistix solver (`_stages.solve_stage`) differentiates itself."""
        m = self.index.shape[0]
        r = jax.vmap(lambda mod, zl, mk: mod.residuals(zl, mk))(
            self.stacked, z[self.index], mask.reshape(m, -1))
        return r.reshape(-1)

    def respond(self, z):
        """The fitted responses of every trace (a Response with a leading trace axis)."""
        return jax.vmap(lambda mod, zl: mod.respond(zl))(self.stacked, z[self.index])


@compiled(lambda model, z: response_structure())
def _respond_all(model: _JointModel, z):
    return model.respond(z)


# ------------------------------------------------------------------------ the fit


def fit_joint(traces, structure, params, settings: Settings, optimizer=None) -> JointFitResult:
    """The joint fit (`fit_decay` with a list of traces; `settings`: its keyword
    arguments)."""
    traces = _check_traces(traces)
    structure = _check_structures(structure, len(traces))
    jp = _joint_problem(traces, structure, params, settings)
    return _fit(jp, optimizer, [tr.source or f"trace[{i}]" for i, tr in enumerate(traces)])


def fit_joint_problems(problems, optimizer, sources) -> JointFitResult:
    """The joint fit of checked problems (of shake-table runs, `fit_shake_table`)."""
    return _fit(joint_of(problems), optimizer, sources)


def _fit(jp: _JointProblem, optimizer, sources) -> JointFitResult:
    transforms = [Transform.of(pb) for pb in jp.problems]
    model = _JointModel.build(jp)
    opt = optimizer_of(optimizer)
    run = run_stages(jp, model, opt, _starting_points(jp, transforms), lm=optimizer is None,
                     outliers=False)
    best = best_start(jp, model, opt, run)
    responses = _responses(jp, model, transforms, best.z)
    unc = _uncertainty(jp, transforms, best)
    out = _result(jp, transforms, run, best, responses, unc, sources)
    keep = jp.samples().reshape(len(jp.problems), -1)
    values0 = {k: float(v) for k, v in jp.problems[0].values0.items()}
    return dataclasses.replace(out, fit_state=(model, keep, np.asarray(best.z), values0))


def _starting_points(jp: _JointProblem, transforms) -> np.ndarray:
    """(starts, P_joint): each trace's starting points (`Transform.starting_points`)
    placed in the joint z (the shared parameters' starts are the same in every trace)."""
    z = np.zeros((jp.starts, len(jp.params)))
    for i, tf in enumerate(transforms):
        z[:, jp.index[i]] = tf.starting_points(jp.starts)
    return z


def _local(jp: _JointProblem, z, i: int) -> np.ndarray:
    return np.asarray(z)[jp.index[i]]


def _responses(jp: _JointProblem, model: _JointModel, transforms, z) -> list:
    """The fitted Response of each trace, on its own samples."""
    res = _respond_all(model, jnp.asarray(z))
    out = []
    for i, pb in enumerate(jp.problems):
        r = res.member(i)
        n = pb.t.size
        r = eqx.tree_at(lambda x: (x.ts, x.u, x.v, x.theta, x.uplift), r,
                        (r.ts[:n], r.u[:n], r.v[:n], r.theta[:n], r.uplift[:n]))
        v = transforms[i].decode(_local(jp, z, i))  # as the sensor reads it
        out.append(_sensor.observe(r, v, pb.t, pb.t_ref))
    return out


def _uncertainty(jp: _JointProblem, transforms, best):
    """(standard errors, correlation, noise sigma [m] of each trace's displacement):
    the Gauss-Newton sandwich A^-1 B A^-1 (A = J^T J, B = J^T diag(s^2) J) with a
    variance s^2 per trace and channel (its RSS over its samples less a share of the
    parameters), in natural units."""
    m, P = len(jp.problems), len(jp.params)
    J, r = best.J, best.r
    per = r.size // m  # residuals of one trace (n, or 2 n with the uplift)
    chans = per // jp.n
    var = np.empty(r.size)
    sigmas = []
    for i, pb in enumerate(jp.problems):
        n_i = pb.t.size
        for c in range(chans):
            sl = slice(i * per + c * jp.n, i * per + c * jp.n + n_i)
            s2 = max(float(np.sum(r[sl] ** 2)) / max(n_i - P / (m * chans), 1.0), 1e-300)
            var[i * per + c * jp.n:i * per + (c + 1) * jp.n] = s2
            if c == 0:
                sigmas.append(math.sqrt(s2) * pb.scale)
    D = np.zeros(P)
    for i, tf in enumerate(transforms):
        D[jp.index[i]] = tf.derivatives(_local(jp, best.z, i))
    try:
        a_inv = np.linalg.inv(J.T @ J)
        cov = np.diag(D) @ (a_inv @ (J.T @ (var[:, None] * J)) @ a_inv) @ np.diag(D)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        safe = np.where(se > 0, se, 1.0)
        corr = cov / np.outer(safe, safe)
    except np.linalg.LinAlgError:
        se, corr = np.full(P, np.inf), np.full((P, P), np.nan)
    return se, corr, sigmas


def _trace_dict(jp: _JointProblem, i: int, source: str, values: dict, se: dict, response,
                sigma):
    pb = jp.problems[i]
    e = np.asarray(getattr(response, pb.channels[0])) - pb.measured(pb.channels[0])
    rms = float(np.sqrt(np.mean(e**2)))
    lack = _lack.lack_of_fit(e, rms, pb.scale, pb.fit_model.describe(),
                             _models.models_above(pb.fit_model, pb.params), t=pb.t,
                             fitted=tuple(p for p in pb.params if p in NUISANCE))
    own = [p for p in OWN if p in pb.params]
    return {
        "source": source,
        "n_points": int(pb.t.size),
        "values": {p: values[p] for p in own},
        "stderr": {p: se[f"{p}[{i}]"] for p in own},
        "fixed": {p: values[p] for p in PER_TRACE if p not in pb.params},
        "rms": rms,
        "sigma": sigma,
        "release": {**pb.release.as_dict(), "t0_start_s": pb.values0["t0"],
                    "u0_start_m": pb.values0["u0"]},
        "lack_of_fit": lack,
    }


def _result(jp, transforms, run, best, responses, unc, sources) -> JointFitResult:
    se, corr, sigmas = unc
    pb0 = jp.problems[0]
    se_of = {p: float(se[j]) for j, p in enumerate(jp.params)}
    per_trace, messages = [], []
    for i, pb in enumerate(jp.problems):
        vals = transforms[i].decode(_local(jp, best.z, i))
        d = _trace_dict(jp, i, sources[i], vals, se_of, responses[i], sigmas[i])
        per_trace.append(d)
        if d["lack_of_fit"]["fires"]:
            messages.append(f"trace[{i}]: {d['lack_of_fit']['message']}")
        if i == 0:
            shared_vals = {p: vals[p] for p in PARAM_NAMES if p in SHARED}
    for m in messages:
        warnings.warn(m, LackOfFitWarning, stacklevel=4)  # fit_decay's caller
    names = tuple(p for p in jp.params if p in SHARED)
    converged = (bool(run.converged[best.index]) and math.isfinite(best.loss)
                 and best.loss < 1e5)
    return JointFitResult(
        names=names, values={p: shared_vals[p] for p in names},
        stderr={p: se_of[p] for p in names},
        fixed={p: shared_vals[p] for p in SHARED
               if p not in names and p in pb0.fit_model.acting},
        start={p: float(pb0.values0[p]) for p in names},
        per_trace=tuple(per_trace), joint_names=jp.params, correlation=np.asarray(corr),
        responses=tuple(responses), loss=best.loss, loss_history=best.history,
        start_losses=best.start_losses, converged=converged, n_iterations=run.n_iter,
        warnings=tuple(messages), model=pb0.fit_model.describe(), notes=pb0.notes,
    )
