"""rockjax.Status: an enumeration that carries its own message (as diffrax's RESULTS)."""

from __future__ import annotations

import equinox as eqx
import pytest

import rockjax
from rockjax._status import status_code, status_message, status_name, status_names


def test_status_is_an_equinox_enumeration_with_messages():
    assert issubclass(rockjax.Status, eqx.Enumeration)
    assert status_names() == ("completed", "overturned", "max_impacts", "solver_failure")
    for name in status_names():
        item = getattr(rockjax.Status, name)
        assert int(item._value) == status_code(name) == rockjax.STATUS[name]
        assert status_name(status_code(name)) == name
        assert rockjax.Status[item] == status_message(status_code(name)) != ""
    assert "u_overturn" in status_message(rockjax.STATUS["overturned"])
    with pytest.raises(ValueError, match="status must be one of"):
        status_code("exploded")


def test_response_message_comes_from_the_enumeration():
    s = rockjax.mcmanus_column()
    res = rockjax.simulate(s, rockjax.FreeVibration(0.1), 0.5, method="rk4")
    assert res.status_name == "completed"
    failed = eqx.tree_at(lambda r: r.status, res, rockjax.STATUS["solver_failure"] + 0 * res.status)
    assert failed.message == "solver_failure: " + status_message(rockjax.STATUS["solver_failure"])
