"""How a run ended: `rockjax.Status`, an enumeration that carries its own message.

As diffrax's `RESULTS`, each entry is an `equinox.Enumeration` item with a message. A
`Response` stores the integer code (so that batched results are plain int arrays that
NumPy, pandas and `jax.vmap` handle); `status_name(code)`, `status_message(code)` and
`status_code(name)` convert.

Only the enumeration's public face is used: its items (``Status.overturned``), the message
of an item (``Status[item]``) and an item's integer code, its one pytree leaf. The names in
code order are `NAMES` (equinox keeps no public list of them; `tests/test_status.py`
checks that `NAMES` and `Status` agree).
"""

from __future__ import annotations

import equinox as eqx
import jax

from ._errors import ParameterError


class Status(eqx.Enumeration):
    """The end of a run: completed, overturned, max_impacts or solver_failure."""

    completed = "the run reached its end time or came to rest"
    overturned = "|u| reached u_overturn: the structure overturned"
    max_impacts = "the run reached its bound on impacts; raise max_impacts to continue"
    solver_failure = (
        "the integration failed (non-finite state or step budget exhausted, typically a "
        "very stiff foundation k_f); use model=\"housner\" (the rigid limit "
        "k_f -> infinity), a fixed-step setting (method=\"rk4\" with more substeps, or dt=), "
        "method=\"dopri5\", or a larger max_steps"
    )


#: the `Status` names in code order (code 0 first)
NAMES = ("completed", "overturned", "max_impacts", "solver_failure")


def _code(item) -> int:
    """An enumeration item's integer code: its one pytree leaf."""
    (value,) = jax.tree_util.tree_leaves(item)
    return int(value)


def status_names() -> tuple[str, ...]:
    """The `Status` names in code order (code 0 first)."""
    return NAMES


def status_code(name: str) -> int:
    """The integer code stored in `Response.status` for a status name."""
    if name not in NAMES:
        raise ParameterError(f"status must be one of {list(NAMES)}, got {name!r}",
                             param="status")
    return _code(getattr(Status, name))


def status_name(code) -> str:
    """The name of an integer code (0 -> "completed", ...)."""
    return NAMES[int(code)]


def status_message(code) -> str:
    """The message that `Status` carries for an integer code."""
    return Status[getattr(Status, status_name(code))]


#: name -> integer code, e.g. ``STATUS["overturned"] == 1`` (kept for compatibility)
STATUS = {name: status_code(name) for name in status_names()}
#: integer code -> name
STATUS_NAMES = {v: k for k, v in STATUS.items()}
