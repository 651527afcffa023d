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
    def from_file(cls, path, *, units=None, scale=1.0, dt=None, format=None, **reader):
        """Read a record file into a `GroundMotion` [m/s²]: `units`, `dt`, `format` and
        `**reader` (`time_tolerance`, `check_plausible`) as `rockjax.read_record`."""
        from ._records import read_record

        rec = read_record(path, units=units, dt=dt, format=format, **reader)
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


class RecordTable(AbstractExcitation):
    r"""The ground motions of a batch in the one form that every integrator consumes.

    A table of records, `table` of shape (n_records, n_samples) [m/s²], each zero-padded
    past its own `lengths` samples, and per member (shape () shared by every member, or
    (N,) one value per member): `record` (the row it runs), `scale`, `u0` [m], `v0` [m/s]
    and the sample step `dt` [s]. The ground acceleration of a member is its record's
    samples linearly interpolated and times `scale`, zero after the record's last sample
    (as `GroundMotion` defines it); `free=True` makes it a free vibration (the table is
    then unused and `dt` is the output grid's step).

    The batched stepper (`RK4`, `Dopri5`) advances all members at once; the event-restart
    integrator runs one member at a time under `jax.vmap` (every per-member field then a
    scalar). `rockjax.simulate_batch` builds it; `as_table` converts a `GroundMotion` or
    a `FreeVibration`.
    """

    table: jnp.ndarray
    lengths: jnp.ndarray
    dt: jnp.ndarray
    record: jnp.ndarray
    scale: jnp.ndarray
    u0: jnp.ndarray
    v0: jnp.ndarray
    free: bool = eqx.field(static=True, default=False)

    #: the fields that may vary per member (the others are shared by the whole batch)
    MEMBER_FIELDS = ("dt", "record", "scale", "u0", "v0")

    @property
    def forced(self) -> bool:
        return not self.free

    def initial_state(self):
        return self.u0, self.v0

    def ground_acceleration(self, t):
        """Ground acceleration [m/s²] of one member (scalar `record`)."""
        if self.free:
            return jnp.zeros_like(t)
        n_tab = self.table.shape[-1]
        n = self.lengths[self.record]
        x = t / self.dt
        i = jnp.clip(jnp.floor(x), 0, n_tab - 2).astype(jnp.int32)
        f = x - i
        row = self.table[self.record]
        a = row[i] * (1.0 - f) + row[i + 1] * f
        inside = (x >= 0) & (x <= n - 1)
        return jnp.where(inside, self.scale * a, 0.0)

    def jump_times(self):
        if self.free:
            return None
        return self.dt * jnp.arange(self.table.shape[-1], dtype=self.table.dtype)

    def first_direction(self):
        """Direction of each member's first motion from rest: opposite to its record's
        first non-zero sample times its scale (+1 for an all-zero record or a free
        vibration); shape of `record`."""
        if self.free:
            return jnp.ones(jnp.shape(self.record), self.table.dtype)
        rows = jnp.arange(self.table.shape[0])
        first = self.table[rows, jnp.argmax(self.table != 0, axis=-1)]  # per record
        d = -jnp.sign(self.scale * first[self.record])
        return jnp.where(d == 0, 1.0, d)


def as_table(excitation, dtype, *, dt=None, n_min=2):
    """`excitation` (a `GroundMotion` of one record, or a `FreeVibration`) as a one-record
    `RecordTable` in `dtype`, the table zero-padded to at least `n_min` samples; a free
    vibration's `dt` [s] is the output grid's step (required)."""
    u0, v0 = (jnp.asarray(x, dtype) for x in excitation.initial_state())
    zero = jnp.zeros((), jnp.int32)
    if not excitation.forced:
        return RecordTable(table=jnp.zeros((1, 2), dtype), lengths=jnp.full((1,), 2),
                           dt=jnp.asarray(dt, dtype), record=zero,
                           scale=jnp.ones((), dtype), u0=u0, v0=v0, free=True)
    acc = jnp.asarray(excitation.accel, dtype)
    pad = max(0, n_min - acc.shape[-1])
    table = jnp.concatenate([acc, jnp.zeros((pad,), dtype)])[None]
    return RecordTable(table=table, lengths=jnp.full((1,), acc.shape[-1], jnp.int32),
                       dt=jnp.asarray(excitation.dt, dtype), record=zero,
                       scale=jnp.asarray(excitation.scale, dtype), u0=u0, v0=v0)
