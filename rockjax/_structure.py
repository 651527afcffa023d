"""The rigid lumped-mass structure on a two-spring foundation (paper §3.1, Fig. 3)."""

from __future__ import annotations

import pathlib
import tomllib
from importlib import resources

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from . import _structure_units
from ._config import ensure_x64
from ._errors import ParameterError

#: the fields of a RockingStructure, in order
FIELDS = ("m_e", "m_b", "H_e", "H_b", "B", "I_eg", "I_bg", "k_f", "g")
_FIELDS = FIELDS


def _as_float_array(x: ArrayLike) -> Float[Array, "..."]:
    """Convert to a floating JAX array, keeping an existing floating dtype (no downcast)."""
    ensure_x64()
    if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jnp.floating):
        # explicit dtype drops a weak type, so jnp.asarray(1.0) and 1.0 trace alike
        return jnp.asarray(x, dtype=x.dtype)
    return jnp.asarray(x, dtype=jnp.result_type(float))


def _is_concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


class RockingStructure(eqx.Module):
    r"""A rigid two-mass structure resting on two compression-only springs at $x=\pm B$.

    Every field is a JAX array (so `jax.grad`, `jax.jacfwd` and `jax.vmap` reach it) in SI
    units. Derived quantities are properties computed from the fields, so they stay
    differentiable.

    **Arguments:**

    - `m_e`: effective lumped mass of the structure [kg].
    - `m_b`: footing mass [kg].
    - `H_e`: height of `m_e` above the base plane [m].
    - `H_b`: height of the footing centroid above the base plane [m].
    - `B`: half-width of the base; the springs sit at $x=\pm B$ [m].
    - `I_eg`: rotary inertia of `m_e` about its own centroid [kg m²].
    - `I_bg`: rotary inertia of `m_b` about its own centroid [kg m²].
    - `k_f`: stiffness of each foundation spring [N/m].
    - `g`: gravitational acceleration [m/s²], default 9.81 as in the paper.

    Concrete (non-traced) values are validated: masses, heights and `B` must be positive,
    inertias non-negative, and the foundation stiff enough to stand,
    $2 k_f B^2 > W H_c$ (otherwise the pre-uplift stiffness, Eq. 15, is not positive).
    A violation raises `ValueError` naming the parameter.

    **Example:**

    ```python
    import rockjax
    s = rockjax.mcmanus_column()
    print(float(s.u_crit), float(s.restitution))  # 0.0055 m, 0.735
    ```
    """

    m_e: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    m_b: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    H_e: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    H_b: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    B: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    I_eg: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    I_bg: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    k_f: Float[Array, "..."] = eqx.field(converter=_as_float_array)
    g: Float[Array, "..."] = eqx.field(converter=_as_float_array, default=9.81)

    def __check_init__(self):
        validate_structure(self)

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_toml(cls, path: str | pathlib.Path, *,
                  check_plausible: bool = True) -> RockingStructure:
        """Read a structure from a TOML file with a `[structure]` table.

        The keys are the field names `m_e, m_b, H_e, H_b, B, I_eg, I_bg, k_f` and the
        optional `g`, in SI units unless the file says otherwise: a `units` key (at the
        top of the file or in the table) names a system of units (see
        `rockjax._structure_units`: ``"m"``, ``"cm"``, ``"mm"``, ``"in"``, ``"N-mm-t"``,
        ``"kN-m-t"``), and a field may carry its own unit as a suffix (``B_mm = 285``,
        ``"k_f_kN/m" = 550``, ``m_e_t = 0.1226``). The structure is in SI whatever the
        file's units. See `data/mcmanus_column.toml` for an example. Unknown or missing
        keys raise `ValueError` naming them; dimensions implausible in SI (a base wider
        than 100 m, a height over 500 m) raise a `ParameterError` with a hint on
        millimetres unless `check_plausible` is False.
        """
        path = pathlib.Path(path)
        if path.is_dir():
            raise IsADirectoryError(f"structure file is a directory: {path}")
        if not path.is_file():
            raise FileNotFoundError(f"structure file not found: {path}")
        try:
            with path.open("rb") as f:
                doc = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"{path}: not valid TOML ({e})") from None
        except UnicodeDecodeError as e:
            raise ValueError(f"{path}: not valid TOML (not UTF-8 text: {e.reason})") from None
        table = doc.get("structure", doc)
        if "structure" in doc and "units" in doc and isinstance(table, dict):
            if "units" in table and table["units"] != doc["units"]:
                raise ValueError(f"{path}: units {doc['units']!r} at the top of the file but "
                                 f"{table['units']!r} in [structure]")
            table = {**table, "units": doc["units"]}
        return cls.from_dict(table, source=str(path), check_plausible=check_plausible)

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "structure",
                  check_plausible: bool = True) -> RockingStructure:
        """Build a structure from a mapping of field names to numbers: SI units, or those
        of a `units` key and of field suffixes as in `from_toml` (the same checks)."""
        if not isinstance(d, dict):
            raise ValueError(f"{source}: expected a table of structure parameters")
        values = _structure_units.to_si(d, source)
        if check_plausible:
            _structure_units.check_plausible(values, d, source)
        return cls(**values)

    def to_dict(self) -> dict[str, float]:
        """The fields as plain Python floats (for scalar structures)."""
        return {k: float(getattr(self, k)) for k in _FIELDS}

    def replace(self, **changes) -> RockingStructure:
        """A copy with some fields changed, e.g. `s.replace(k_f=1e6)` (re-validated)."""
        values = {k: getattr(self, k) for k in _FIELDS}
        unknown = sorted(set(changes) - set(_FIELDS))
        if unknown:
            raise ValueError(f"unknown parameter(s) {', '.join(unknown)}")
        values.update(changes)
        return RockingStructure(**values)

    def astype(self, dtype) -> RockingStructure:
        """A copy with every field cast to `dtype` (e.g. `jnp.float32` for speed)."""
        return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), self)

    # ------------------------------------------------------------ derived: mass
    @property
    def mass(self):
        r"""Total mass $m_e + m_b$ [kg], the inertia of the SDOF Eq. 1."""
        return self.m_e + self.m_b

    @property
    def W(self):
        r"""Weight $W = (m_e + m_b) g$ [N] (Eq. 5)."""
        return self.mass * self.g

    @property
    def H_c(self):
        r"""Height of the system centroid $H_c = (m_e H_e + m_b H_b)/(m_e + m_b)$ [m]."""
        return (self.m_e * self.H_e + self.m_b * self.H_b) / self.mass

    @property
    def R_c(self):
        r"""Distance from a base corner to the system centroid $\sqrt{B^2 + H_c^2}$ [m]."""
        return jnp.hypot(self.B, self.H_c)

    @property
    def alpha_c(self):
        r"""Slenderness angle of the centroid $\arctan(B/H_c)$ [rad].

        The paper prints $\alpha_c = B/H_c$; the angle is its arctangent (see
        `docs/errata.md`).
        """
        return jnp.arctan2(self.B, self.H_c)

    @property
    def R_e(self):
        r"""Distance from a base corner to the effective mass $\sqrt{B^2 + H_e^2}$ [m]."""
        return jnp.hypot(self.B, self.H_e)

    @property
    def alpha_e(self):
        r"""Angle of the effective mass from the corner, $\arctan(B/H_e)$ [rad]."""
        return jnp.arctan2(self.B, self.H_e)

    @property
    def R_b(self):
        r"""Distance from a base corner to the footing centroid $\sqrt{B^2 + H_b^2}$ [m]."""
        return jnp.hypot(self.B, self.H_b)

    @property
    def alpha_b(self):
        r"""Angle of the footing centroid from the corner, $\arctan(B/H_b)$ [rad]."""
        return jnp.arctan2(self.B, self.H_b)

    # ------------------------------------------------------ derived: foundation
    @property
    def delta_0(self):
        r"""Initial settlement on the two springs $\delta_0 = W/(2k_f)$ [m] (Eq. 4)."""
        return self.W / (2.0 * self.k_f)

    @property
    def theta_crit(self):
        r"""Rotation at lift-off $\theta_{crit} = W/(2 k_f B)$ [rad] (Eq. 10, small angle).

        The geometrically exact lift-off rotation is $\arcsin(\delta_0/B)$; the two differ
        by $O(\theta^3)$.
        """
        return self.W / (2.0 * self.k_f * self.B)

    @property
    def u_crit(self):
        r"""Top displacement at lift-off $u_{crit} = W H_e/(2 k_f B)$ [m] (Eq. 11).

        Eq. 11 is exact for the rigid body on two springs: $u = H_e \sin\theta$ (Eq. 6) with
        the exact lift-off rotation $\sin\theta = \delta_0 / B$.
        """
        return self.W * self.H_e / (2.0 * self.k_f * self.B)

    @property
    def K1(self):
        r"""Pre-uplift lateral stiffness $K_1 = (2 k_f B^2 - W H_c)/H_e^2$ [N/m] (Eqs 13, 15)."""
        return (2.0 * self.k_f * self.B**2 - self.W * self.H_c) / self.H_e**2

    @property
    def P_crit(self):
        r"""Lateral force at lift-off from the linear branch [N] (Eqs 14, 17 corrected).

        $P_{crit} = \frac{W}{H_e}\left(B - \frac{W H_c}{2 k_f B}\right) = K_1 u_{crit}$.
        """
        return self.W / self.H_e * (self.B - self.W * self.H_c / (2.0 * self.k_f * self.B))

    @property
    def P_crit2(self):
        r"""Eq. 18 evaluated at $\theta_{crit}$ [N] (Eq. 19).

        $P_{crit2} = W \frac{R_c \sin(\alpha_c - \theta_{crit})}
        {R_e \cos(\alpha_e - \theta_{crit})}$
        """
        t = self.theta_crit
        return (
            self.W * self.R_c * jnp.sin(self.alpha_c - t) / (self.R_e * jnp.cos(self.alpha_e - t))
        )

    @property
    def u_overturn(self):
        r"""Displacement at which the restoring force vanishes [m] (paper §3.3).

        $u_{overturn} = R_e[\sin\alpha_e + \sin(\alpha_c - \alpha_e)]$: the centroid is
        directly above the pivot ($\theta = \alpha_c$). The geometrically exact value, which
        includes the rotation about the centreline before lift-off, is smaller by
        $B(1-\cos\theta_{crit})$, about $4\times10^{-6}$ m for Table 1.
        """
        return self.R_e * (jnp.sin(self.alpha_e) + jnp.sin(self.alpha_c - self.alpha_e))

    @property
    def restitution(self):
        r"""Housner's coefficient of restitution for the two-mass body (Eq. 3).

        $r = \left(\frac{m_e(H_e^2-B^2)+I_{eg} + m_b(H_b^2-B^2)+I_{bg}}
        {m_e(H_e^2+B^2)+I_{eg} + m_b(H_b^2+B^2)+I_{bg}}\right)^2$, the ratio of the
        squared angular speeds after and before an impact (Eq. 2), from conservation of
        angular momentum about the corner that takes over. About 0.735 for Table 1.
        """
        B2 = self.B**2
        num = self.m_e * (self.H_e**2 - B2) + self.I_eg + self.m_b * (self.H_b**2 - B2) + self.I_bg
        den = self.m_e * (self.H_e**2 + B2) + self.I_eg + self.m_b * (self.H_b**2 + B2) + self.I_bg
        return (num / den) ** 2

    @property
    def I_O(self):
        r"""Rotary inertia of the whole body about a base corner [kg m²]."""
        return self.I_eg + self.m_e * self.R_e**2 + self.I_bg + self.m_b * self.R_b**2

    def evaluated(self) -> Evaluated:
        """Every field and derived quantity evaluated once, as a pytree with the same
        attribute names (for integrator loops, which would otherwise recompute the derived
        quantities at every step)."""
        return Evaluated({k: getattr(self, k) for k in (*_FIELDS, *DERIVED, "mass", "I_O")})

    def derived(self) -> dict[str, float]:
        """Every derived quantity as a Python float (angles in rad, also in deg as `*_deg`)."""
        out = {}
        for name in DERIVED:
            out[name] = float(getattr(self, name))
        for name in ("alpha_c", "alpha_e", "alpha_b", "theta_crit"):
            out[name + "_deg"] = float(jnp.degrees(getattr(self, name)))
        return out


@jax.tree_util.register_pytree_node_class
class Evaluated:
    """A structure's fields and derived quantities as plain attributes (a pytree)."""

    def __init__(self, values: dict):
        self.__dict__.update(values)

    def tree_flatten(self):
        keys = tuple(sorted(self.__dict__))
        return [self.__dict__[k] for k in keys], keys

    @classmethod
    def tree_unflatten(cls, keys, leaves):
        return cls(dict(zip(keys, leaves)))


DERIVED = (
    "W",
    "H_c",
    "R_c",
    "alpha_c",
    "R_e",
    "alpha_e",
    "R_b",
    "alpha_b",
    "delta_0",
    "theta_crit",
    "u_crit",
    "K1",
    "P_crit",
    "P_crit2",
    "u_overturn",
    "restitution",
)


def validate_structure(s: RockingStructure) -> None:
    """Raise `ValueError` naming the parameter if a concrete structure is not physical.

    Traced values (inside `jit`, `grad`, `vmap`) cannot be inspected and are not checked.
    """
    import numpy as np

    def vals(name):
        x = getattr(s, name)
        if not _is_concrete(x):
            return None
        return np.asarray(x)

    for name in _FIELDS:
        v = vals(name)
        if v is not None and not np.all(np.isfinite(v)):
            raise ParameterError(f"{name} must be finite, got {v}", param=name)
    for name, what in (
        ("m_e", "mass"),
        ("m_b", "mass"),
        ("H_e", "height"),
        ("H_b", "height"),
        ("B", "half-width"),
        ("k_f", "spring stiffness"),
        ("g", "gravitational acceleration"),
    ):
        v = vals(name)
        if v is not None and np.any(v <= 0):
            raise ParameterError(f"{name} ({what}) must be positive, got {v}", param=name)
    for name in ("I_eg", "I_bg"):
        v = vals(name)
        if v is not None and np.any(v < 0):
            raise ParameterError(f"{name} (rotary inertia) must be non-negative, got {v}",
                                 param=name)
    if all(_is_concrete(getattr(s, n)) for n in _FIELDS):
        lhs = np.asarray(2.0 * s.k_f * s.B**2)
        rhs = np.asarray(s.W * s.H_c)
        if np.any(lhs <= rhs):
            kmin = np.asarray(s.W * s.H_c / (2.0 * s.B**2))
            raise ParameterError(
                f"k_f is too soft for the structure to stand: need 2 k_f B^2 > W H_c, "
                f"i.e. k_f > {np.array2string(kmin, precision=6)} N/m "
                f"(got k_f = {np.asarray(s.k_f)}); the pre-uplift stiffness K1 (Eq. 15) "
                "would not be positive", param="k_f"
            )


def _data_file(name: str):
    """A file of the project's data/ folder, installed as the package rockjax._data."""
    try:
        res = resources.files("rockjax._data") / name
        if res.is_file():
            return res
    except ModuleNotFoundError:
        pass
    return pathlib.Path(__file__).resolve().parents[1] / "data" / name


def mcmanus_column() -> RockingStructure:
    """The McManus (1980) uplifting steel column of Table 1 (`data/mcmanus_column.toml`).

    B = 0.285 m, H_e = 1.050 m, k_f = 550 kN/m, H_b = 0.062 m, I_bg = 4.33 kg m²,
    m_b = 44.7 kg, I_eg = 37.57 kg m², m_e = 122.6 kg, g = 9.81 m/s².
    """
    res = _data_file("mcmanus_column.toml")
    with res.open("rb") as f:
        doc = tomllib.load(f)
    return RockingStructure.from_dict(doc["structure"], source="mcmanus_column.toml")
