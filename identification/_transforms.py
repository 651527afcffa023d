r"""Natural parameters <-> the optimiser's unconstrained coordinates z.

$$z = \big(\log(k_f - k_{f,min}),\ \operatorname{logit} r,\ u_0/u_{s},\
(t_0 - t_{ref})/10\,\mathrm{ms},\ \log c_f,\ o/u_s,\ o_{up}/u_s,\ d/(u_s/\mathrm{s}),
\ o_\theta/\theta_s\big),$$

($o$, $o_{up}$, $o_\theta$: the sensor zeros of the displacement, uplift and rotation
channels, $d$ the drift of the displacement channel [m/s]: the nuisance parameters, linear
in the residuals; $\theta_s$ the amplitude of the rotation channel [rad])
where $k_{f,min} = W H_c / (2B^2)$ is the stability limit (Eq. 15), $u_s$ the trace
amplitude and $t_{ref}$ the starting value of $t_0$. For the models whose k_f is bounded
(`identification._models.k_f_cap`), $\log(k_f - k_{f,min})$ is bounded smoothly below
$\log(k_{cap} - k_{f,min})$ (`k_f_of_z`). `Transform` is the Python side (floats: the
starting points, the values and derivatives at the optimum); `decode` is the traced map
used inside the compiled residuals.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from . import _models

T_SCALE = 0.01  # s, unit of t0 in the unconstrained coordinates
LINEAR = ("offset", "offset_uplift", "drift", "offset_theta")
"""The nuisance parameters (sensor zeros, drift): linear in the residuals, z = value / u_s
(drift per second; offset_theta: z = value / theta_s)."""


def k_f_of_z(z, span):
    """log(k_f - k_min) from its coordinate z: z itself, or with a smooth upper bound
    `span` = log(k_cap - k_min): span - softplus(span - z), = z - e^(z - span) well below."""
    return z if span is None else span - jax.nn.softplus(span - z)


def decode(z, params: tuple, values0: dict, k_min, scale, t_ref, k_span,
           theta_scale=1.0) -> dict:
    """Traced: z (the fitted parameters, order `params`) -> natural values of all the
    parameters (`values0` for the others); the inverse of `Transform.encode`."""
    out = dict(values0)
    for i, name in enumerate(params):
        zi = z[i]
        if name == "k_f":
            out["k_f"] = k_min + jnp.exp(k_f_of_z(zi, k_span))
        elif name == "r":
            out["r"] = jax.nn.sigmoid(zi)
        elif name == "u0":
            out["u0"] = zi * scale
        elif name == "c_f":
            out["c_f"] = jnp.exp(zi)
        elif name in LINEAR:
            out[name] = zi * (theta_scale if name == "offset_theta" else scale)
        else:
            out["t0"] = t_ref + zi * T_SCALE
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Transform:
    """Natural parameters <-> the optimiser's unconstrained coordinates z (module docstring),
    on the Python side (floats); `decode` is the traced inverse.

    z holds the fitted parameters only (order `params`); the others keep `values0`.
    """

    params: tuple
    values0: dict
    k_min: float
    scale: float
    t_ref: float
    offsets: tuple = _models.SDOF_START_OFFSETS  # (log k_f, dissipation) shift of each start
    k_cap: float | None = None  # smooth upper bound of k_f (see k_f_of_z)
    theta_scale: float = 1.0  # amplitude of the rotation channel [rad]: offset_theta's unit

    def _unit(self, p: str) -> float:
        """The unit of z of a nuisance parameter."""
        return self.theta_scale if p == "offset_theta" else self.scale

    def encode(self, v: dict) -> dict:
        """Natural values of all the parameters -> their z coordinates."""
        y = math.log(v["k_f"] - self.k_min)
        if self.k_cap is not None:  # the inverse of k_f_of_z
            span = math.log(self.k_cap - self.k_min)
            y = span - math.log(math.expm1(span - y))
        return {
            "k_f": y,
            "r": math.log(v["r"] / (1.0 - v["r"])),
            "u0": v["u0"] / self.scale,
            "t0": (v["t0"] - self.t_ref) / T_SCALE,
            "c_f": math.log(v["c_f"]) if v["c_f"] > 0 else -math.inf,  # fitted: > 0
            **{p: v[p] / self._unit(p) for p in LINEAR},
        }

    def decode(self, z) -> dict:
        """The optimiser's coordinates of the fitted parameters -> natural values of all
        the parameters (floats; the inverse of `encode`, as `decode`)."""
        out = {k: float(v) for k, v in self.values0.items()}
        for p, zi in zip(self.params, (float(x) for x in z)):
            if p == "k_f":
                y = zi
                if self.k_cap is not None:
                    span = math.log(self.k_cap - self.k_min)
                    x = span - zi
                    y = span - (max(x, 0.0) + math.log1p(math.exp(-abs(x))))
                out["k_f"] = self.k_min + math.exp(y)
            elif p == "r":
                out["r"] = 1.0 / (1.0 + math.exp(-zi))
            elif p == "u0":
                out["u0"] = zi * self.scale
            elif p == "c_f":
                out["c_f"] = math.exp(zi)
            elif p in LINEAR:
                out[p] = zi * self._unit(p)
            else:
                out["t0"] = self.t_ref + zi * T_SCALE
        return out

    def derivatives(self, z) -> list:
        """d(natural value)/dz of each fitted parameter at the point `z` (floats)."""
        out = []
        for p, zi in zip(self.params, z):
            if p == "k_f" and self.k_cap is not None:
                span = math.log(self.k_cap - self.k_min)
                x = span - zi
                soft = max(x, 0.0) + math.log1p(math.exp(-abs(x)))
                out.append(math.exp(span - soft) / (1.0 + math.exp(-x)))
            elif p in ("k_f", "c_f"):
                out.append(math.exp(zi))
            elif p == "r":
                s_ = 1.0 / (1.0 + math.exp(-zi))
                out.append(s_ * (1 - s_))
            elif p == "u0" or p in LINEAR:
                out.append(self.scale if p == "u0" else self._unit(p))
            else:
                out.append(T_SCALE)
        return out

    def starting_points(self, n: int) -> np.ndarray:
        """`n` starting points (n, P): `values0`, then k_f and the dissipation (logit r,
        log c_f) shifted (`offsets`)."""
        z0 = self.encode(self.values0)
        base = np.array([z0[p] for p in self.params])
        starts_z = []
        for i in range(n):
            dk, dr = self.offsets[i % len(self.offsets)]
            dk *= 1 + i // len(self.offsets)
            zi = base.copy()
            for j, p in enumerate(self.params):
                zi[j] += dk if p == "k_f" else dr if p in ("r", "c_f") else 0.0
            starts_z.append(zi)
        return np.stack(starts_z)


# -------------------------------------------------------- residuals, Jacobian

    @classmethod
    def of(cls, pb) -> Transform:
        """The transform of a `Problem`."""
        return cls(pb.params, pb.values0, pb.k_min, pb.scale, pb.t_ref,
                   _models.start_offsets(pb.fit_model), pb.k_cap, pb.theta_scale)
