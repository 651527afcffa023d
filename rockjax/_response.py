"""The result of a simulation."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._status import STATUS as STATUS, status_message, status_name, STATUS_NAMES as STATUS_NAMES


class Response(eqx.Module):
    """Time history and summary of one run of `rockjax.simulate` (SI units).

    - `ts` [s], and on it `u` [m] (top displacement), `v` [m/s], `theta` [rad] and `uplift`
      [m] (of the lifted corner, paper §4). After the run stops (overturning, rest, failure)
      the arrays hold the state at that moment.
    - `impact_times` [s]: padded with `inf` beyond `n_impacts`.
    - `peak_u` [m]: the peak |u| of the continuous solution (not of the grid);
      `peak_uplift` [m].
    - `status`: 0 completed, 1 overturned, 2 max_impacts, 3 solver_failure (`status_name`).
    - `t_overturn` [s]: when |u| reached `u_overturn` (`inf` if it did not).
    """

    ts: jnp.ndarray
    u: jnp.ndarray
    v: jnp.ndarray
    theta: jnp.ndarray
    uplift: jnp.ndarray
    impact_times: jnp.ndarray
    n_impacts: jnp.ndarray
    peak_u: jnp.ndarray
    peak_uplift: jnp.ndarray
    status: jnp.ndarray
    t_overturn: jnp.ndarray

    @property
    def status_name(self) -> str:
        """The status as text (for an unbatched response)."""
        return status_name(self.status)

    @property
    def message(self) -> str:
        """A one-line explanation of the status, with the remedy for a failure (for an
        unbatched response)."""
        name = self.status_name
        n = int(self.n_impacts)
        if name == "completed":
            return f"completed: the run reached its end time or came to rest ({n} impacts)"
        if name == "overturned":
            return (
                f"overturned: |u| reached u_overturn at t = {float(self.t_overturn):.6g} s "
                f"(after {n} impacts)"
            )
        if name == "max_impacts":
            budget = int(np.shape(self.impact_times)[-1])
            why = (
                f"the run reached the bound of {budget} impacts"
                if n >= budget
                else f"the run ran out of event segments after {n} impacts (the segment "
                f"budget grows with max_impacts = {budget}; a very stiff k_f causes this, "
                "where method=\"dopri5\" is the better remedy)"
            )
            return f"max_impacts: {why}; raise max_impacts to continue"
        return f"solver_failure: {status_message(self.status)}"

    @property
    def impacts(self) -> np.ndarray:
        """The impact times [s] without padding (for an unbatched response)."""
        return np.asarray(self.impact_times)[: int(self.n_impacts)]

    def summary(self) -> dict:
        """peak_u, peak_uplift, n_impacts, impact_times, status, t_overturn as plain Python."""
        t_ot = float(self.t_overturn)
        return {
            "peak_u": float(self.peak_u),
            "peak_uplift": float(self.peak_uplift),
            "n_impacts": int(self.n_impacts),
            "impact_times": [float(t) for t in self.impacts],
            "status": self.status_name,
            "t_overturn": t_ot if np.isfinite(t_ot) else None,
        }
