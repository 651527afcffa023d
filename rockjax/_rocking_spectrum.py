r"""`rockjax.rocking_spectrum`: the rocking spectrum of a ground-motion record
(Makris & Konstantinidis 2003): the peak rotation $\theta_{max}/\alpha$ of uniform rigid
blocks of one slenderness $\alpha$ across a range of sizes, given by Housner's frequency
parameter $p = \sqrt{3g/(4R)}$ [rad/s] ($R$ the half-diagonal), with the
equivalent-linear-oscillator estimate of the design guides beside it.

**The time histories.** Block $i$ is a uniform rectangle of half-width $b = R\sin\alpha$ and
half-height $h = R\cos\alpha$ (mass 1000 kg, as two halves at the centroid, each with the
rotary inertia $m(b^2+h^2)/6$, so that $I_O = \frac43 m R^2$ about a corner and
$W R / I_O = p^2$). All sizes go through `rockjax.simulate_batch` at once (one batch,
fixed-step RK4 with the impacts located inside each step, no impact limit) on a model of
the ladder: `"rigid_body"` (the default: the body's own rotational equation, which on
stiff springs, `k_f` = 1e10 N/m, is Housner's rigid block: its peak rotation is within
0.4 % of an independent integration of Housner's equation on El Centro at p = 1 rad/s,
alpha = 0.15) or `"housner"` (the paper's SDOF Eq. 1 with the rigid-foundation law: a
lateral-displacement reduction, not Housner's rotational equation: on El Centro at
alpha = 0.15 its theta/alpha is 4 % above rigid_body's at p = 1 rad/s, 48 % at 1.5, and it
overturns the p = 2 block that rigid_body keeps at 0.49). The restitution is
Housner's, $r = (1 - \frac32\sin^2\alpha)^2$ for a uniform block (Eq. 3 of the paper for
these masses), or a given $r$ (the ratio of the squared angular speeds after and before an
impact). The run goes to the record's end plus `tail`; a block that overturns is marked as
such ($\theta_{max}/\alpha$ is then NaN).

**The equivalent linear oscillator** (Priestley, Evison & Carr 1978, "Seismic response of
structures free to rock on their foundations", Bull. NZSEE 11(3), adopted by FEMA 356
(2000) for rocking; the procedure that Makris & Konstantinidis 2003 show to be
unreliable). A block rocking with amplitude $\theta$ is replaced by a linear SDOF of

- period $T(\theta) = \frac{4}{p}\cosh^{-1}\!\frac{1}{1-\theta/\alpha}$, Housner's (1963)
  exact period of free rocking of amplitude $\theta$;
- damping ratio $\zeta = -\ln(r)/(2\pi) = -\ln(\eta)/\pi$ ($\eta = \sqrt r$, the ratio of
  angular speeds across an impact): the viscous damping that removes, in half a cycle,
  the fraction $1 - r$ of the energy that one impact removes (one impact per half cycle of
  rocking), which is constant for a given block;

and the displacement of its mass, the record's elastic spectral displacement
$S_d(T, \zeta)$ (exact for the piecewise-linear record: `rockjax.spectral_acceleration`
$/\omega^2$), is the lateral displacement of the centroid, $S_d = \theta\,h = \theta R\cos
\alpha$. The design procedure iterates $\theta_{k+1} = S_d(T(\theta_k),\zeta)/h$ from a
small rotation; here its first fixed point is found directly: the smallest
$\theta \in (0, \alpha)$ where $S_d(T(\theta),\zeta)/h - \theta$ turns from positive to
negative (a scan of 256 rotations, then bisection to $10^{-6}\alpha$). None in $(0,\alpha)$:
the estimate predicts overturning. $S_d/h < \theta$ already at the smallest rotation, or a
PGA below $g\tan\alpha$: no rocking ($\theta = 0$).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ._batch import simulate_batch
from ._config import ensure_x64
from ._errors import ParameterError
from ._execution import Execution
from ._intensity import spectral_acceleration
from ._records import Record
from ._response import STATUS_NAMES
from ._structure import RockingStructure
from ._units import G_STANDARD
from .integrators import RK4
from .models import get_model

__all__ = ["RockingSpectrum", "equivalent_linear_rotation", "rocking_spectrum",
           "uniform_block"]

#: the models a rocking spectrum runs on
MODELS = ("housner", "rigid_body")
#: the block's mass [kg] (the peak rotation does not depend on it)
BLOCK_MASS = 1000.0
#: the springs of `rigid_body` [N/m] for BLOCK_MASS: stiff (the rigid-block limit)
DEFAULT_K_F = 1e10
#: spring step: omega h <= 0.5 per RK4 substep
_OMEGA_H = 0.5
_N_SCAN = 256


def uniform_block(p, alpha, *, k_f=DEFAULT_K_F, mass=BLOCK_MASS, g=G_STANDARD):
    r"""The uniform rectangular blocks of frequency parameter `p` [rad/s] (scalar or
    array) and slenderness `alpha` [rad]: half-diagonal $R = 3g/(4p^2)$, half-width
    $R\sin\alpha$, half-height $R\cos\alpha$, `mass` [kg] as two halves at the centroid,
    springs `k_f` [N/m]. A `RockingStructure` (array fields for an array `p`)."""
    p = np.asarray(p, float)
    R = 3.0 * g / (4.0 * p**2)
    b, h = R * math.sin(alpha), R * math.cos(alpha)
    inertia = 0.5 * mass * (b * b + h * h) / 3.0
    return RockingStructure(m_e=mass / 2, m_b=mass / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                            I_bg=inertia, k_f=np.broadcast_to(float(k_f), p.shape).copy()
                            if p.ndim else float(k_f), g=g)


def housner_r(alpha) -> float:
    r"""Housner's restitution of a uniform rectangular block, $r = (1 -
    \frac32\sin^2\alpha)^2$ (squared angular speeds after / before an impact)."""
    return (1.0 - 1.5 * math.sin(alpha) ** 2) ** 2


def _period(p, ratio):
    """Housner's period of free rocking [s] of amplitude theta = ratio * alpha."""
    return 4.0 / p * np.arccosh(1.0 / (1.0 - ratio))


def equivalent_linear_rotation(record, p, alpha, *, r=None, scale=1.0, g=G_STANDARD):
    r"""The equivalent-linear-oscillator estimate of the peak rotation of uniform blocks
    (module docstring: Priestley, Evison & Carr 1978; FEMA 356): for each `p` [rad/s],
    (theta / alpha, period T [s], damping ratio zeta, overturned) as arrays; theta / alpha
    is NaN where the estimate predicts overturning."""
    p = np.atleast_1d(np.asarray(p, float))
    r = housner_r(alpha) if r is None else float(r)
    zeta = -math.log(r) / (2 * math.pi)
    rec = record if scale == 1.0 else Record(dt=record.dt, accel=np.asarray(record.accel)
                                             * scale, source=record.source)
    h = 3.0 * g / (4.0 * p**2) * math.cos(alpha)

    def excess(ratio, idx):
        """S_d(T(theta), zeta) / h - theta, over alpha, for the blocks `idx` (ratio:
        (len(idx),) or (len(idx), K))."""
        ratio = np.asarray(ratio, float)
        shape = (-1,) + (1,) * (ratio.ndim - 1)
        T = _period(p[idx].reshape(shape), ratio)
        sa = spectral_acceleration(rec, T.ravel(), zeta).reshape(T.shape)
        return sa * (T / (2 * math.pi)) ** 2 / h[idx].reshape(shape) / alpha - ratio

    everyone = np.arange(p.size)
    grid = np.geomspace(1e-4, 1.0 - 1e-6, _N_SCAN)
    f = excess(np.broadcast_to(grid, (p.size, grid.size)), everyone)
    out = np.full(p.size, np.nan)
    over = np.zeros(p.size, bool)
    lo, hi = np.zeros(p.size), np.zeros(p.size)
    for i in range(p.size):
        if rec.pga <= g * math.tan(alpha) or f[i, 0] <= 0:
            out[i] = 0.0  # no rocking
            continue
        down = np.nonzero(f[i] <= 0)[0]
        if down.size == 0:
            over[i] = True  # no fixed point below alpha: overturns
            continue
        lo[i], hi[i] = grid[down[0] - 1], grid[down[0]]
    todo = np.nonzero(hi > 0)[0]
    a, b = lo[todo], hi[todo]
    for _ in range(60):
        if todo.size == 0 or np.all(b - a <= 1e-6):
            break
        mid = 0.5 * (a + b)
        up = excess(mid, todo) > 0
        a, b = np.where(up, mid, a), np.where(up, b, mid)
    out[todo] = 0.5 * (a + b)
    T = np.where(np.isfinite(out) & (out > 0), _period(p, np.where(np.isfinite(out), out,
                                                                    0.5)), np.nan)
    return out, T, zeta, over


@dataclasses.dataclass(frozen=True)
class RockingSpectrum:
    r"""The rocking spectrum of a record (SI units; module docstring).

    - `p` [rad/s]: the blocks' frequency parameters; `R` [m] their half-diagonals
      $3g/(4p^2)$; `alpha` [rad] their slenderness; `r` the restitution used.
    - `theta_over_alpha`: the peak $|\theta|/\alpha$ of each block's time history (NaN
      where it overturned); `overturned`: bool per block; `status` (text per block:
      completed, overturned, max_impacts, solver_failure); `n_impacts`.
    - `eq_theta_over_alpha`: the equivalent-linear estimate (NaN where it predicts
      overturning), `eq_overturned`, `eq_period` [s] (its SDOF's period at the estimate),
      `eq_damping` (its damping ratio).
    - `model`, `k_f` [N/m] (rigid_body's springs), `scale` (on the record), `record` (its
      source), `pga` [m/s²] (of the scaled record), `wall_time` [s].
    """

    p: np.ndarray
    R: np.ndarray
    alpha: float
    r: float
    theta_over_alpha: np.ndarray
    overturned: np.ndarray
    status: tuple
    n_impacts: np.ndarray
    eq_theta_over_alpha: np.ndarray
    eq_overturned: np.ndarray
    eq_period: np.ndarray
    eq_damping: float
    model: str
    k_f: float
    scale: float
    record: str
    pga: float
    wall_time: float

    @property
    def period(self) -> np.ndarray:
        r"""$2\pi/p$ [s], the abscissa some authors use."""
        return 2 * np.pi / self.p

    def to_dict(self) -> dict:
        """Plain Python for JSON (NaN as None)."""
        def lst(x):
            return [None if isinstance(v, float) and not math.isfinite(v) else v
                    for v in np.asarray(x).tolist()]
        return {"p_rad_s": lst(self.p), "R_m": lst(self.R), "alpha_rad": self.alpha,
                "r": self.r, "theta_over_alpha": lst(self.theta_over_alpha),
                "overturned": lst(self.overturned), "status": list(self.status),
                "n_impacts": lst(self.n_impacts),
                "eq_theta_over_alpha": lst(self.eq_theta_over_alpha),
                "eq_overturned": lst(self.eq_overturned), "eq_period_s": lst(self.eq_period),
                "eq_damping": self.eq_damping, "model": self.model, "k_f": self.k_f,
                "scale": self.scale, "record": self.record, "pga_m_s2": self.pga,
                "wall_time_s": self.wall_time}

    def report(self) -> str:
        """A table: p, R, the time history's theta/alpha and the equivalent-linear one."""
        def cell(v, over):
            return "overturns" if over else f"{v:.4f}"
        lines = [f"rocking spectrum of {self.record} x {self.scale:g} (PGA {self.pga:.4g} "
                 f"m/s2): alpha {self.alpha:.4g} rad, r {self.r:.4g}, model {self.model}"
                 + (f" (k_f {self.k_f:.3g} N/m)" if self.model == "rigid_body" else ""),
                 f"equivalent linear oscillator: T(theta) = 4/p acosh(1/(1 - theta/alpha)), "
                 f"zeta = -ln(r)/(2 pi) = {self.eq_damping:.4f}",
                 f"{'p [rad/s]':>10} {'R [m]':>10} {'theta/alpha':>12} {'eq. linear':>12}"
                 f" {'impacts':>8}"]
        for i in range(self.p.size):
            lines.append(f"{self.p[i]:10.4g} {self.R[i]:10.4g} "
                         f"{cell(self.theta_over_alpha[i], self.overturned[i]):>12} "
                         f"{cell(self.eq_theta_over_alpha[i], self.eq_overturned[i]):>12} "
                         f"{int(self.n_impacts[i]):8d}")
        lines.append(f"{self.p.size} blocks in {self.wall_time:.3g} s")
        return "\n".join(lines)

    def plot(self, ax=None, *, label=None):
        r"""$\theta_{max}/\alpha$ against $p$ (the literature's axes), the time histories
        as a line with dots, overturning as crosses at 1, the equivalent-linear estimate
        dashed. Returns the axes."""
        if ax is None:
            from ._plotting import new_figure
            ax = new_figure(figsize=(6, 4)).subplots()
        lab = label or f"{self.model}, alpha = {self.alpha:.3g}"
        line, = ax.plot(self.p, self.theta_over_alpha, ".-", label=lab)
        if np.any(self.overturned):
            ax.plot(self.p[self.overturned], np.ones(int(self.overturned.sum())), "x",
                    color=line.get_color(), label=f"{lab}: overturns")
        ax.plot(self.p, np.where(self.eq_overturned, np.nan, self.eq_theta_over_alpha), "--",
                color=line.get_color(), alpha=0.7, label=f"equivalent linear (alpha = "
                f"{self.alpha:.3g})")
        if np.any(self.eq_overturned):
            ax.plot(self.p[self.eq_overturned], np.ones(int(self.eq_overturned.sum())), "+",
                    color=line.get_color(), alpha=0.7)
        ax.set_xlabel("p [rad/s]  (larger blocks to the left; R = 3g / (4 p²))")
        ax.set_ylabel("θ_max / α")
        ax.set_ylim(0, 1.1)
        ax.axhline(1.0, color="0.6", lw=0.8)
        ax.legend(fontsize=7)
        return ax


def _check(record, alpha, p, model, r, scale, tail, substeps):
    if not isinstance(record, Record):
        raise ParameterError(f"record must be a rockjax.Record, got {type(record).__name__}",
                             param="record")
    if not (isinstance(alpha, (int, float)) and 0 < alpha < math.pi / 4):
        raise ParameterError(f"alpha must be a slenderness in (0, pi/4) rad, got {alpha!r}",
                             param="alpha")
    p = np.atleast_1d(np.asarray(p, float))
    if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p) & (p > 0)):
        raise ParameterError(f"p must be positive frequency parameters [rad/s], got {p!r}",
                             param="p")
    if model not in MODELS:
        raise ParameterError(f"model must be one of {', '.join(MODELS)}, got {model!r}",
                             param="model")
    if r is not None and not (0 <= r <= 1):
        raise ParameterError(f"r must lie in [0, 1], got {r!r}", param="r")
    if not (math.isfinite(scale) and scale > 0):
        raise ParameterError(f"scale must be positive, got {scale!r}", param="scale")
    if not (math.isfinite(tail) and tail >= 0):
        raise ParameterError(f"tail must be >= 0 [s], got {tail!r}", param="tail")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ParameterError(f"substeps must be a positive integer, got {substeps!r}",
                             param="substeps")
    return p


def rocking_spectrum(record, alpha, p, *, model="rigid_body", r=None, scale=1.0,
                     k_f=DEFAULT_K_F, tail=5.0, substeps=4, equivalent_linear=True,
                     execution=None) -> RockingSpectrum:
    r"""The rocking spectrum of `record`: peak $\theta/\alpha$ of uniform blocks of
    slenderness `alpha` for each frequency parameter `p`, and the equivalent-linear
    estimate beside it (module docstring: the formulae).

    **Arguments:**

    - `record`: a `rockjax.Record` (m/s²); `scale`: a factor on it (default 1).
    - `alpha` [rad]: the blocks' slenderness, in (0, π/4).
    - `p` [rad/s]: the frequency parameters $\sqrt{3g/(4R)}$, a list or array (a block
      of half-diagonal R [m] has $p = \sqrt{3g/(4R)}$: R = 1 m is p = 2.71 rad/s).
    - `model`: ``"rigid_body"`` (default: the body's own equation on springs `k_f`
      [N/m], default 1e10 for the 1000-kg block, its rigid-block limit: Housner's block)
      or ``"housner"`` (the paper's SDOF with the rigid-foundation law).
    - `r`: the restitution (squared angular speeds after/before an impact); default
      Housner's $(1 - \frac32\sin^2\alpha)^2$.
    - `tail` [s]: free rocking after the record's end (default 5).
    - `substeps`: RK4 steps per sample step (rigid_body: more where the springs need
      them, omega h <= 0.5).
    - `equivalent_linear`: compute the estimate (default True; False: NaN).
    - `execution`: a `rockjax.Execution` (devices, chunk size, progress).

    **Returns:** a `RockingSpectrum` (`.plot()`, `.report()`, `.to_dict()`).
    """
    ensure_x64()
    start = time.perf_counter()
    tail, scale = float(tail), float(scale)
    p = _check(record, alpha, p, model, r, scale, tail, substeps)
    alpha = float(alpha)
    r_used = housner_r(alpha) if r is None else float(r)
    blocks = uniform_block(p, alpha, k_f=k_f)
    m = get_model(model)
    omega = float(np.max(m.frequency(blocks.evaluated())))
    if omega > 0:
        substeps = max(substeps, math.ceil(record.dt * omega / _OMEGA_H))
    execution = execution or Execution(progress=False)
    out = simulate_batch(blocks, [record], scale=np.full(p.size, scale),
                         record=np.zeros(p.size, int), r=r_used, tail=tail, model=m,
                         integrator=RK4(substeps=substeps, max_impacts=2**30),
                         summary_only=True, fidelity_warning=False, execution=execution)
    status = np.asarray(out.status)
    theta = np.abs(np.asarray(m.theta_uplift_of_u(blocks, out.peak_u)[0], float))
    overturned = status == 1
    ratio = np.where(overturned, np.nan, theta / alpha)
    if equivalent_linear:
        eq, T, zeta, eq_over = equivalent_linear_rotation(record, p, alpha, r=r_used,
                                                          scale=scale, g=float(blocks.g))
    else:
        eq, T, zeta, eq_over = (np.full(p.size, np.nan), np.full(p.size, np.nan),
                                -math.log(r_used) / (2 * math.pi), np.zeros(p.size, bool))
    return RockingSpectrum(
        p=p, R=3.0 * float(blocks.g) / (4.0 * p**2), alpha=alpha, r=r_used,
        theta_over_alpha=ratio, overturned=overturned,
        status=tuple(STATUS_NAMES[int(s)] for s in status),
        n_impacts=np.asarray(out.n_impacts), eq_theta_over_alpha=eq, eq_overturned=eq_over,
        eq_period=T, eq_damping=zeta, model=model, k_f=float(k_f), scale=scale,
        record=record.source, pga=float(record.pga * scale),
        wall_time=time.perf_counter() - start)
