"""rockjax.Status: an enumeration that carries its own message (as diffrax's RESULTS)."""

from __future__ import annotations

import equinox as eqx
import jax
import pytest

import rockjax
from rockjax._status import status_code, status_message, status_name, status_names


def test_status_is_an_equinox_enumeration_with_messages():
    assert issubclass(rockjax.Status, eqx.Enumeration)
    assert status_names() == ("completed", "overturned", "max_impacts", "solver_failure")
    for name in status_names():
        item = getattr(rockjax.Status, name)
        (code,) = jax.tree_util.tree_leaves(item)  # the item's code, its one pytree leaf
        assert int(code) == status_code(name) == rockjax.STATUS[name]
        assert status_name(status_code(name)) == name
        assert rockjax.Status[item] == status_message(status_code(name)) != ""
    assert "u_overturn" in status_message(rockjax.STATUS["overturned"])
    with pytest.raises(rockjax.ParameterError, match="status must be one of") as e:
        status_code("exploded")
    assert e.value.param == "status"


def test_no_private_attributes_of_equinox_or_jax():
    import pathlib

    src = "".join(p.read_text() for p in pathlib.Path(rockjax.__file__).parent.rglob("*.py"))
    for private in ("_name_to_item", "_index_to_message", "._value", "jax._src"):
        assert private not in src, private


def test_response_message_comes_from_the_enumeration():
    s = rockjax.mcmanus_column()
    res = rockjax.simulate(s, rockjax.FreeVibration(0.1), 0.5, method="rk4")
    assert res.status_name == "completed"
    failed = eqx.tree_at(lambda r: r.status, res, rockjax.STATUS["solver_failure"] + 0 * res.status)
    assert failed.message == "solver_failure: " + status_message(rockjax.STATUS["solver_failure"])
