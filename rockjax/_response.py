"""The result of a simulation."""

from __future__ import annotations

import dataclasses

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
    def batch_shape(self) -> tuple:
        """The batch shape: `()` for one run of `simulate`, `(N,)` for `simulate_batch`."""
        return tuple(np.shape(self.status))

    def member(self, index) -> "Response":
        """The response of one member of a batch (an int or a tuple of ints)."""
        if not self.batch_shape:
            raise ValueError("member: this Response is not batched")
        shared_ts = np.ndim(self.ts) < np.ndim(self.u)  # one time grid for every member
        return dataclasses.replace(
            self,
            **{
                f.name: np.asarray(getattr(self, f.name))
                if f.name == "ts" and shared_ts
                else np.asarray(getattr(self, f.name))[index]
                for f in dataclasses.fields(self)
            },
        )

    def _each(self, fn):
        """`fn(member)` for one run, or an array of them (dtype object) for a batch."""
        shape = self.batch_shape
        if not shape:
            return fn(self)
        out = np.empty(shape, dtype=object)
        for idx in np.ndindex(*shape):
            out[idx] = fn(self.member(idx))
        return out

    @property
    def status_name(self) -> str | np.ndarray:
        """The status as text (an array of them for a batch)."""
        if self.batch_shape:
            return np.vectorize(status_name, otypes=[str])(np.asarray(self.status))
        return status_name(self.status)

    @property
    def message(self) -> str | np.ndarray:
        """A one-line explanation of the status, with the remedy for a failure (an array of
        them for a batch)."""
        return self._each(_message)

    @property
    def impacts(self) -> np.ndarray:
        """The impact times [s] without the `inf` padding (`n_impacts` is their number); for
        a batch, an object array holding one such array per member."""
        return self._each(lambda m: np.asarray(m.impact_times)[: int(m.n_impacts)])

    def peak_theta(self, structure, model) -> float:
        """The peak rotation |theta| [rad] of one run of `model` (a `rockjax.get_model`
        model): from the exact `peak_u` where the model maps u to theta (the SDOF models),
        else the largest |theta| on the output grid up to overturning."""
        if model.kinematics_of_u:
            return abs(float(model.theta_uplift_of_u(structure, self.peak_u)[0]))
        ts, theta = np.asarray(self.ts), np.abs(np.asarray(self.theta))
        t_ot = float(self.t_overturn)
        return float(np.max(theta[ts <= t_ot] if np.isfinite(t_ot) else theta))

    def report(self, structure, model) -> str:
        """One run as text: status, peak |u| [m] and when, peak rotation [rad] (and over
        `alpha_c`), peak uplift [m], impacts, and when it overturned or where it ended.

        **Arguments:** `structure`, the `RockingStructure` run; `model`, the model it ran
        with (a `rockjax.get_model` model, for the rotation: `peak_theta`).

        ```python
        s, model = rockjax.mcmanus_column(), rockjax.get_model("simplified")
        res = rockjax.simulate(s, rockjax.FreeVibration(0.05), 2.0, model=model)
        print(res.report(s, model))
        ```
        """
        out, theta = _summary(self), self.peak_theta(structure, model)
        lines = [f"status        {out['status']}",
                 f"peak |u|      {out['peak_u']:.6g} m at t = {out['t_peak']:.6g} s",
                 f"peak theta    {theta:.6g} rad = {theta / float(structure.alpha_c):.4g} alpha_c",
                 f"peak uplift   {out['peak_uplift']:.6g} m", f"impacts       {out['n_impacts']}"]
        if out["t_overturn"] is not None:
            return "\n".join([*lines, f"t_overturn    {out['t_overturn']:.6g} s"])
        return "\n".join([*lines, f"residual u    {out['residual_u']:.6g} m at t = "
                                   f"{out['t_end']:.6g} s"])

    def to_csv(self, path):
        """Write the time history of one run as CSV, one row per output time, header
        `t_s,u_m,v_m_s,theta_rad,uplift_m` (`ts` [s], `u` [m], `v` [m/s], `theta` [rad],
        `uplift` [m]); a batch: take a run first (`member`)."""
        if self.batch_shape:
            raise TypeError(f"to_csv writes one run; this is a batch of {self.batch_shape}: "
                            "take one with member(index)")
        cols = {"t_s": self.ts, "u_m": self.u, "v_m_s": self.v, "theta_rad": self.theta,
                "uplift_m": self.uplift}
        np.savetxt(path, np.column_stack([np.asarray(c) for c in cols.values()]), delimiter=",",
                   header=",".join(cols), comments="", fmt="%.10g")

    def summary(self) -> dict | list:
        """The results as plain Python (SI units: m, s), for JSON: `peak_u` [m] and `t_peak`
        [s] (when |u| peaked, from the cubic Hermite interpolant of u, v on `ts`),
        `peak_uplift` [m], `n_impacts`, `impact_times` [s], `status`, `t_overturn` [s] (None
        if it did not overturn), `t_end` [s] (the last output time) and `residual_u` [m]
        (u at `t_end`; None after overturning). A batch gives a (nested) list of them."""
        if self.batch_shape:
            return self._each(_summary).tolist()
        return _summary(self)


def _message(res) -> str:
    name = status_name(res.status)
    n = int(res.n_impacts)
    if name == "completed":
        return f"completed: the run reached its end time or came to rest ({n} impacts)"
    if name == "overturned":
        return (
            f"overturned: |u| reached u_overturn at t = {float(res.t_overturn):.6g} s "
            f"(after {n} impacts)"
        )
    if name == "max_impacts":
        budget = int(np.shape(res.impact_times)[-1])
        why = (
            f"the run reached the bound of {budget} impacts"
            if n >= budget
            else f"the run ran out of event segments after {n} impacts (the segment "
            f"budget grows with max_impacts = {budget}; a very stiff k_f causes this, "
            "where method=\"dopri5\" is the better remedy)"
        )
        return f"max_impacts: {why}; raise max_impacts to continue"
    return f"solver_failure: {status_message(res.status)}"


def peak_time(ts, u, v) -> float:
    """When |u| peaks [s]: the grid sample of largest |u|, refined on the cubic Hermite
    interpolant of (u, v) over its two neighbouring intervals."""
    ts, u, v = (np.asarray(x, dtype=np.float64) for x in (ts, u, v))
    i = int(np.argmax(np.abs(u)))
    best_t, best = float(ts[i]), abs(float(u[i]))
    for j in (i - 1, i):
        if j < 0 or j + 1 >= ts.size or not ts[j + 1] > ts[j]:
            continue
        h = ts[j + 1] - ts[j]
        x = np.linspace(0.0, 1.0, 257)
        h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
        h01, h11 = -2 * x**3 + 3 * x**2, x**3 - x**2
        p = h00 * u[j] + h10 * h * v[j] + h01 * u[j + 1] + h11 * h * v[j + 1]
        k = int(np.argmax(np.abs(p)))
        if abs(p[k]) > best:
            best_t, best = float(ts[j] + x[k] * h), abs(float(p[k]))
    return best_t


def _summary(res) -> dict:
    t_ot = float(res.t_overturn)
    overturned = bool(np.isfinite(t_ot))
    ts = np.asarray(res.ts)
    keep = ts <= t_ot if overturned else np.ones(ts.shape, bool)
    t_peak = t_ot if overturned else peak_time(ts[keep], np.asarray(res.u)[keep],
                                                 np.asarray(res.v)[keep])
    return {
        "peak_u": float(res.peak_u),
        "t_peak": t_peak,
        "peak_uplift": float(res.peak_uplift),
        "n_impacts": int(res.n_impacts),
        "impact_times": [float(t) for t in np.asarray(res.impact_times)[: int(res.n_impacts)]],
        "status": status_name(res.status),
        "t_overturn": t_ot if overturned else None,
        "t_end": float(ts[-1]),
        "residual_u": None if overturned else float(np.asarray(res.u)[-1]),
    }
