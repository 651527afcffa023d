r"""Excitations of Eq. 1: a free-vibration release and a ground-motion record."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._structure import _as_float_array


class AbstractExcitation(eqx.Module):
    """What drives the structure: initial conditions and a ground acceleration."""

    def ground_acceleration(self, t):
        """Ground acceleration $\\ddot u_g(t)$ [m/s²]."""
        return jnp.zeros_like(t)

    def initial_state(self):
        """Initial (u0 [m], v0 [m/s])."""
        z = jnp.zeros(())
        return z, z

    def jump_times(self):
        """Times [s] where the forcing has kinks, for the step-size controller (or None)."""
        return None

    @property
    def forced(self) -> bool:
        """Whether a ground motion acts (static)."""
        return False

    def first_direction(self):
        """Direction (+1 or -1) of the first motion from rest (+1 without forcing)."""
        return jnp.ones(())


class FreeVibration(AbstractExcitation):
    r"""Release from a displacement `u0` [m] with velocity `v0` [m/s], no ground motion.

    Eq. 1 with $P(t) = 0$: $(m_e + m_b)\ddot u + k(u) = 0$ (the paper's Fig. 9 test).
    """

    u0: jnp.ndarray = eqx.field(converter=_as_float_array)
    v0: jnp.ndarray = eqx.field(converter=_as_float_array, default=0.0)

    def __check_init__(self):
        for name in ("u0", "v0"):
            x = getattr(self, name)
            if not _is_tracer(x) and not np.all(np.isfinite(np.asarray(x))):
                raise ValueError(f"{name} must be finite, got {np.asarray(x)}")

    def initial_state(self):
        return self.u0, self.v0


def _is_tracer(x):
    import jax

    return isinstance(x, jax.core.Tracer)


class GroundMotion(AbstractExcitation):
    r"""A ground-acceleration record: samples `accel` [m/s²] every `dt` [s], times `scale`.

    Eq. 1 with $P(t) = -(m_e + m_b)\,\mathrm{scale}\cdot\ddot u_g(t)$. The record is
    linearly interpolated between samples (sample $i$ at $t = i\,dt$) and is zero after its
    end. The structure starts at rest unless `u0`, `v0` are given.

    Build it from a file with `GroundMotion.from_file(path, units="g", scale=1.0)` (PEER
    AT2, two columns t, a, or one column with `dt=`), or from arrays.
    """

    dt: jnp.ndarray = eqx.field(converter=_as_float_array)
    accel: jnp.ndarray = eqx.field(converter=_as_float_array)
    scale: jnp.ndarray = eqx.field(converter=_as_float_array, default=1.0)
    u0: jnp.ndarray = eqx.field(converter=_as_float_array, default=0.0)
    v0: jnp.ndarray = eqx.field(converter=_as_float_array, default=0.0)

    def __check_init__(self):
        if not _is_tracer(self.dt):
            dt = np.asarray(self.dt)
            if dt.size == 0 or not (np.all(np.isfinite(dt)) and float(np.min(dt)) > 0):
                raise ValueError(f"dt must be positive and finite [s], got {dt}")
        if self.accel.ndim < 1 or self.accel.shape[-1] < 2:
            raise ValueError("accel must hold at least 2 samples")
        if not _is_tracer(self.accel) and not np.all(np.isfinite(np.asarray(self.accel))):
            raise ValueError("accel holds NaN or inf values")
        for name in ("scale", "u0", "v0"):
            x = getattr(self, name)
            if not _is_tracer(x) and not np.all(np.isfinite(np.asarray(x))):
                raise ValueError(f"{name} must be finite, got {np.asarray(x)}")

    @classmethod
    def from_file(cls, path, *, units=None, scale=1.0, dt=None, format=None):
        """Read a record file (see `rockjax.read_record`) into a `GroundMotion` [m/s²]."""
        from ._records import read_record

        rec = read_record(path, units=units, dt=dt, format=format)
        return cls(dt=rec.dt, accel=np.asarray(rec.accel), scale=scale)

    @classmethod
    def from_record(cls, record, *, scale=1.0):
        """A `GroundMotion` from a `rockjax.Record` (already in m/s²)."""
        return cls(dt=record.dt, accel=np.asarray(record.accel), scale=scale)

    @property
    def duration(self):
        """Length of the record [s]."""
        return self.dt * (self.accel.shape[-1] - 1)

    def ground_acceleration(self, t):
        n = self.accel.shape[-1]
        x = t / self.dt
        i = jnp.clip(jnp.floor(x), 0, n - 2).astype(jnp.int32)
        f = x - i
        a = self.accel[i] * (1.0 - f) + self.accel[i + 1] * f
        inside = (x >= 0) & (x <= n - 1)
        return jnp.where(inside, self.scale * a, 0.0)

    def initial_state(self):
        return self.u0, self.v0

    def jump_times(self):
        return self.dt * jnp.arange(self.accel.shape[-1], dtype=self.dt.dtype)

    @property
    def forced(self) -> bool:
        return True

    def first_direction(self):
        """Direction of the first motion from rest: opposite to the first non-zero sample
        (+1 for an all-zero record)."""
        a = self.accel
        nz = jnp.argmax(a != 0)
        d = -jnp.sign(self.scale * a[nz])
        return jnp.where(d == 0, 1.0, d)


class PaddedGroundMotion(GroundMotion):
    r"""A `GroundMotion` whose `accel` is zero-padded past its record's end `end` [s] (one
    record of a batch over records of different lengths, on a common grid): the ground
    acceleration is zero after `end`, as it is after the last sample of an unpadded record,
    instead of falling linearly to the padding over one step. Internal to
    `rockjax.simulate_batch`."""

    end: jnp.ndarray = eqx.field(converter=_as_float_array, default=np.inf)

    def ground_acceleration(self, t):
        return jnp.where(t <= self.end, super().ground_acceleration(t), 0.0)
