"""The statistical baselines an outcome fit is judged against, and k-fold cross-validation.

- the constant model: P(topple) = the fraction toppled (1 parameter);
- the three-parameter probit: P = Φ(b0 + b1 ln A + b2 ln T) (ln T is ln(PGV/PGA) plus a
  constant for one pulse kind, so this is the probit in (ln PGA, ln PGV/PGA)). A run at zero
  amplitude has ln A = -inf: with b1 > 0 it stood with probability 1 (log 1 = 0), as in the
  physics model.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.special import log_ndtr


def constant_nll(toppled, weight, p=None):
    """(NLL, p) of the constant model; `p` None: the weighted fraction toppled."""
    y, w = np.asarray(toppled, float), np.asarray(weight, float)
    if p is None:
        p = float(np.sum(w * y) / np.sum(w))
    p = min(max(p, 1e-12), 1 - 1e-12)
    return float(-np.sum(w * (y * np.log(p) + (1 - y) * np.log1p(-p)))), p


def _probit_terms(b, lnA, lnT, y, pos):
    s = b[0] + b[1] * lnA + b[2] * lnT
    ll = np.where(y == 1, log_ndtr(s), log_ndtr(-s))
    return np.where(pos, ll, 0.0)


def probit_fit(amplitude, period, toppled, weight):
    """(NLL, coefficients b0, b1, b2) of the probit Φ(b0 + b1 ln A + b2 ln T), A [m/s²], T
    [s], by BFGS from the origin and a few starts; weights 0/1 select the runs."""
    A, T = np.asarray(amplitude, float), np.asarray(period, float)
    y, w = np.asarray(toppled, int), np.asarray(weight, float)
    pos = A > 0
    lnA = np.log(np.where(pos, A, 1.0))
    lnT = np.log(T)
    mA, sA = np.mean(lnA[pos & (w > 0)]), np.std(lnA[pos & (w > 0)]) or 1.0
    mT, sT = np.mean(lnT[w > 0]), np.std(lnT[w > 0]) or 1.0
    zA, zT = (lnA - mA) / sA, (lnT - mT) / sT

    def f(c):
        return -np.sum(w * _probit_terms(c, zA, zT, y, pos))

    best = None
    for c0 in ([0.0, 1.0, 0.0], [0.0, 3.0, 1.0], [0.0, 3.0, -1.0]):
        res = minimize(f, np.asarray(c0), method="BFGS")
        if best is None or res.fun < best.fun:
            best = res
    c = best.x
    b1, b2 = c[1] / sA, c[2] / sT
    b = np.array([c[0] - b1 * mA - b2 * mT, b1, b2])
    return float(best.fun), b


def probit_log_lik(b, amplitude, period, toppled):
    """log P of each run under the probit `b` (zero amplitude: stood, log 1)."""
    A = np.asarray(amplitude, float)
    pos = A > 0
    return _probit_terms(b, np.log(np.where(pos, A, 1.0)), np.log(np.asarray(period, float)),
                         np.asarray(toppled, int), pos)


def folds(n, k, seed):
    """k folds of the runs 0..n-1, shuffled by `numpy.random.default_rng(seed)`."""
    if not (isinstance(k, int) and 2 <= k <= n):
        raise ValueError(f"k must be an integer from 2 to the number of runs ({n}), got {k!r}")
    return np.array_split(np.random.default_rng(seed).permutation(n), k)
