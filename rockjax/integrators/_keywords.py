"""The keyword form of choosing an integrator (`method="rk4", substeps=8`, ...), kept
working as a compatibility path: it builds the integrator object that `integrator=` takes.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._checks import check_settings
from ._integrators import _adjoint_name, AbstractIntegrator, Dopri5, EventRestart, RK4

CLASSES = {"diffrax": EventRestart, "rk4": RK4, "dopri5": Dopri5}
#: every keyword of the old form, and the integrator field it sets
KEYWORDS = ("method", "solver", "rtol", "atol", "max_steps", "max_impacts", "adjoint",
            "jump_ts", "dt", "substeps", "max_pieces")


def _same(a, b) -> bool:
    if a is b:
        return True
    try:
        return bool(np.all(np.asarray(a == b)))
    except Exception:  # noqa: BLE001 (values that do not compare)
        return False


def _check_agrees(integrator, keywords):
    """Every keyword given next to `integrator=` must say what the integrator says."""
    for name, val in keywords.items():
        if name == "method":
            ok = val == integrator.method
        else:
            field = {f.name for f in dataclasses.fields(integrator)}
            ok = name in field and _same(getattr(integrator, name), val)
        if not ok:
            kind = type(integrator).__name__
            raise ValueError(
                f"{name}={val!r} contradicts integrator={kind}(...): set it on the integrator "
                f"(e.g. rockjax.integrators.{kind}(...)) and leave out {name}="
            )


def from_keywords(integrator, keywords, *, defaults, default, where):
    """The integrator of an entry point called with `integrator=` and/or the old keywords.

    - `integrator`: an `AbstractIntegrator` or None;
    - `keywords`: the old keywords given (`KEYWORDS`; others are a `TypeError`);
    - `defaults`: the entry point's integrator per `method` when only keywords are given
      (so `method="dopri5"` keeps that entry point's tolerances);
    - `default`: the `method` when none is given; `where`: the entry point's name.

    A keyword that contradicts `integrator=` raises `ValueError` naming it; keywords that
    do not apply to the chosen method are ignored, as they always were, and so is a
    keyword given as None.
    """
    unknown = sorted(set(keywords) - set(KEYWORDS))
    if unknown:
        raise TypeError(f"{where}() got an unexpected keyword argument {unknown[0]!r}")
    keywords = {k: v for k, v in keywords.items() if v is not None}  # None: not given
    if integrator is not None:
        if not isinstance(integrator, AbstractIntegrator):
            raise ValueError(
                "integrator must be a rockjax.integrators.AbstractIntegrator (EventRestart, "
                f"RK4, Dopri5), got {integrator!r}"
            )
        _check_agrees(integrator, keywords)
        return integrator
    method = keywords.get("method", default)
    if method not in CLASSES:
        raise ValueError(f"method must be 'diffrax', 'rk4' or 'dopri5', got {method!r}")
    if "adjoint" in keywords:
        _adjoint_name(keywords["adjoint"])
    base = defaults[method]
    if len(keywords) == 0 or set(keywords) == {"method"}:
        return base
    check_settings(method=method, rtol=keywords.get("rtol", 1.0),
                   atol=keywords.get("atol", 1.0),
                   max_impacts=keywords.get("max_impacts", 1), dt=keywords.get("dt"),
                   substeps=keywords.get("substeps"), max_steps=keywords.get("max_steps", 1))
    fields = {f.name for f in dataclasses.fields(base)}
    given = {k: v for k, v in keywords.items() if k in fields}
    return dataclasses.replace(base, **given)
