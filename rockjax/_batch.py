r"""Batches of simulations: `rockjax.simulate_batch`, chunked, sharded and with progress.

Three integrators share one interface:

- `"rk4"` (default): the fast path of `rockjax._fast`, classical RK4 on the record's grid
  (`substeps` per record interval) with every event located inside its step;
- `"dopri5"`: the same loop with Dormand–Prince 5(4) steps under error control (`rtol`,
  `atol`), for a full time history at a set tolerance;
- `"diffrax"`: `rockjax.simulate` (the event-restart diffrax solve) under `jax.vmap`.
"""

from __future__ import annotations

import functools
import math
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import _fast
from ._excitation import AbstractExcitation, FreeVibration, GroundMotion
from ._kinematics import theta_from_u, uplift
from ._response import Response, STATUS_NAMES
from ._restoring import get_model
from ._structure import _FIELDS, RockingStructure

METHODS = ("rk4", "dopri5", "diffrax")
_MEMBER = ("scale", "u0", "v0", "r", "record")


class Summary(eqx.Module):
    """Per-member summaries of a batch (arrays of shape `(N,)`, SI units).

    `peak_u` [m] (peak |u| of the continuous solution), `peak_uplift` [m], `n_impacts`,
    `status` (0 completed, 1 overturned, 2 max_impacts, 3 solver_failure) and `t_overturn`
    [s] (`inf` if it did not overturn).
    """

    peak_u: jnp.ndarray
    peak_uplift: jnp.ndarray
    n_impacts: jnp.ndarray
    status: jnp.ndarray
    t_overturn: jnp.ndarray

    def __len__(self):
        return int(np.shape(self.peak_u)[0])

    @property
    def status_names(self) -> list[str]:
        """The status of each member as text."""
        return [STATUS_NAMES[int(s)] for s in np.asarray(self.status)]

    def to_dict(self) -> dict[str, np.ndarray]:
        """The summaries as NumPy arrays (status as text), e.g. for `pandas.DataFrame`."""
        return {
            "peak_u": np.asarray(self.peak_u),
            "peak_uplift": np.asarray(self.peak_uplift),
            "n_impacts": np.asarray(self.n_impacts),
            "status": np.asarray(self.status_names),
            "t_overturn": np.asarray(self.t_overturn),
        }


def _length(name, x):
    """Batch length of an input: None for a scalar, n for shape (n,); else an error."""
    shape = np.shape(x)
    if len(shape) == 0:
        return None
    if len(shape) == 1:
        return shape[0]
    raise ValueError(
        f"{name} must be a scalar or a 1-D array (one value per run), got shape {shape}"
    )


def _resolve(structure, excitation, scale, r, u0, v0, record):
    """The batch: N and each per-member input as a scalar or an (N,) array."""
    if not isinstance(structure, RockingStructure):
        raise ValueError(f"structure must be a RockingStructure, got {type(structure).__name__}")
    if not isinstance(excitation, AbstractExcitation):
        raise ValueError(
            f"excitation must be a FreeVibration or GroundMotion, got {type(excitation).__name__}"
        )
    free = isinstance(excitation, FreeVibration)
    if not free and not isinstance(excitation, GroundMotion):
        raise ValueError("simulate_batch supports FreeVibration and GroundMotion excitations")
    members = {}
    if free:
        members["u0"] = excitation.u0 if u0 is None else u0
        members["v0"] = excitation.v0 if v0 is None else v0
        if scale is not None or record is not None:
            raise ValueError("scale and record apply to a GroundMotion, not a FreeVibration")
        members["scale"] = 1.0
        members["record"] = 0
        table = None
    else:
        members["u0"] = excitation.u0 if u0 is None else u0
        members["v0"] = excitation.v0 if v0 is None else v0
        members["scale"] = excitation.scale if scale is None else scale
        if np.ndim(excitation.dt) != 0:
            raise ValueError(
                "the records of a batch must share one time step: dt must be a "
                "scalar (resample the records to a common dt)"
            )
        acc = np.asarray(excitation.accel)
        if acc.ndim == 1:
            acc = acc[None]
        elif acc.ndim != 2:
            raise ValueError(
                f"accel must be 1-D (one record) or 2-D (records x samples), got shape {acc.shape}"
            )
        if record is None:
            record = 0 if acc.shape[0] == 1 else np.arange(acc.shape[0])
        rec = np.asarray(record)
        if (
            not np.issubdtype(rec.dtype, np.integer)
            or np.any(rec < 0)
            or np.any(rec >= acc.shape[0])
        ):
            raise ValueError(
                f"record must hold integer indices into the {acc.shape[0]} "
                f"record(s) of excitation.accel, got {rec}"
            )
        members["record"] = rec
        table = acc
    members["r"] = structure.restitution if r is None else r
    lengths = {}
    for name, x in members.items():
        n = _length(name, x)
        if n is not None and n != 1:
            lengths[name] = n
    for name in _FIELDS:
        n = _length(name, getattr(structure, name))
        if n is not None and n != 1:
            lengths[name] = n
    sizes = set(lengths.values())
    if len(sizes) > 1:
        detail = ", ".join(f"{k}: {v}" for k, v in lengths.items())
        raise ValueError(
            f"batched inputs must all have the same length ({detail}); build the "
            "combinations first, e.g. with numpy.meshgrid"
        )
    N = sizes.pop() if sizes else 1
    for name, x in members.items():
        a = np.asarray(x)
        if name != "record" and not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite, got {a}")
    rr = np.asarray(members["r"])
    if np.any(rr < 0) or np.any(rr > 1):
        raise ValueError(f"r must lie in [0, 1], got {rr}")
    return N, members, table, free


def _take(x, sl, N):
    """Slice one chunk of a per-member input (scalars are shared)."""
    a = np.asarray(x)
    if a.ndim == 0:
        return a
    if a.shape[0] == 1:
        return a[0]
    return a[sl]


@functools.cache
def _sharded(n_devices):
    devices = np.array(jax.local_devices()[:n_devices])
    return jax.sharding.Mesh(devices, ("batch",))


def _fast_chunk(batched, shared, table, dt_rec, t1, cfg, n_devices):
    """Run one chunk through the fast integrator, split over `n_devices` local devices."""

    def kernel(batched):
        vals = {**shared, **batched}
        s = RockingStructure(**{k: vals[k] for k in _FIELDS})
        out = _fast.run(s, table, vals["record"], dt_rec, vals["scale"], vals["u0"],
                        vals["v0"], vals["r"], t1, cfg)
        if cfg.full:  # batch axis first, as the sharding (and every other output) has it
            out = dict(out, u=out["u"].T, v=out["v"].T)
        return out

    if n_devices == 1:
        return kernel(batched)
    P = jax.sharding.PartitionSpec
    mesh = _sharded(n_devices)
    # shard_map, not automatic partitioning: each device runs its own loop, and the
    # "does any member need another piece" tests stay local (no cross-device sync per step)
    f = jax.shard_map(
        kernel, mesh=mesh, in_specs=(P("batch"),), out_specs=P("batch"), check_vma=False
    )
    return f(batched)


_fast_chunk_jit = eqx.filter_jit(_fast_chunk)


def _diffrax_chunk(batched, shared, table, dt_rec, t1, ts, cfg, free):
    from ._simulate import _simulate

    def one(b):
        vals = {**shared, **b}
        s = RockingStructure(**{k: vals[k] for k in _FIELDS})
        if free:
            exc = FreeVibration(vals["u0"], vals["v0"])
        else:
            exc = GroundMotion(
                dt=dt_rec,
                accel=table[vals["record"]],
                scale=vals["scale"],
                u0=vals["u0"],
                v0=vals["v0"],
            )
        return _simulate(s, exc, t1, ts, vals["r"], cfg)

    return jax.vmap(one)(batched)


_diffrax_chunk_jit = eqx.filter_jit(_diffrax_chunk)


def _progress(total, enabled, desc):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, leave=False)


def simulate_batch(
    structure,
    excitation,
    t1,
    *,
    scale=None,
    r=None,
    u0=None,
    v0=None,
    record=None,
    model="simplified",
    impact="paper",
    method="rk4",
    substeps=None,
    dt=None,
    rtol=1e-8,
    atol=1e-10,
    ts=None,
    summary_only=False,
    max_impacts=1024,
    max_pieces=None,
    chunk_size=None,
    devices=None,
    progress=None,
):
    r"""Many simulations of Eq. 1 at once: any mix of structures, r, u0, v0, scales, records.

    Each batched input is a 1-D array with one value per run (all of the same length N);
    scalars are shared. Batched inputs are the fields of `structure` (e.g.
    `structure.replace(k_f=np.linspace(...))`), the keyword arguments `scale`, `r`, `u0`,
    `v0`, `record`, and the same fields of `excitation`. Several records of one time step go
    in one `GroundMotion` with `accel` of shape (n_records, n_samples) (pad the shorter
    ones with zeros), and `record` picks one per run (default: one run per record).

    **Arguments:**

    - `structure`, `excitation`, `t1` [s], `model`, `impact`, `r`: as `rockjax.simulate`.
    - `method`: `"rk4"` (default) fixed steps of the record's dt / `substeps` with events
      located inside each step (the fast path); `"dopri5"`: adaptive Dormand–Prince 5(4)
      steps to `rtol`, `atol` inside the same loop; `"diffrax"`: `rockjax.simulate` under
      `vmap` (every member waits for the slowest).
    - `substeps`: RK4 steps per record interval (default 4; for a free vibration, steps per
      `dt`, default 1). With `"dopri5"` it only caps the step size (default 1). Accuracy
      against speed: the peak-u error falls about 16x per halving of the step; on El
      Centro x1.0 it is about 1e-5, 1e-6, 1e-7 for 1, 2, 4, and over scales 0.1-2.0
      (near overturning the response is more sensitive) at worst 1e-3, 3e-4, 2e-5
      (`benchmarks/results.md`).
    - `dt` [s]: the step (and output grid) of a free vibration with `"rk4"`/`"dopri5"`
      (default min(t1 / 4000, 10 ms)).
    - `ts` [s]: output times (full responses only). Fast methods compute the response on
      their grid and interpolate (cubic Hermite) to `ts`.
    - `summary_only`: return a `Summary` (peak_u, peak_uplift, n_impacts, status,
      t_overturn) and store no time history.
    - `max_pieces`: event-localised pieces per step (default 4 for rk4, 32 for the rigid
      `housner` model, whose settling impacts crowd; 4096 for dopri5).
    - `chunk_size`: runs per compiled call (memory stays bounded); the last chunk is
      padded, so every chunk reuses one compilation. Default: 8192 summaries, or as many
      full responses as fit in about 256 MB.
    - `devices`: how many local devices to split each chunk over (default: all of
      `jax.local_devices()`; on a CPU set
      `XLA_FLAGS=--xla_force_host_platform_device_count=<cores>` before importing jax).
    - `progress`: show a tqdm bar (default: when there is more than one chunk).

    **Returns:** a `Summary`, or a `Response` whose arrays have a leading batch axis of
    length N (`impact_times` has shape (N, max_impacts)). Failures come back per member as
    `status`, never as NaN.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    gm = rockjax.GroundMotion.from_file("IELC180.AT2", units="g")
    out = rockjax.simulate_batch(s, gm, 40.0, scale=np.linspace(0.1, 2.0, 10_000),
                                 summary_only=True)
    out.peak_u, out.status
    ```
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    from ._simulate import IMPACT_RULES

    if impact not in IMPACT_RULES:
        raise ValueError(f"impact must be one of {IMPACT_RULES}, got {impact!r}")
    model = get_model(model)
    if model.two_dof:
        raise ValueError("model two_spring_2dof is not batched: run it with rockjax.simulate "
                         "(simulate_batch takes the SDOF models)")
    t1f = np.asarray(t1, dtype=float)
    if t1f.ndim != 0 or not np.isfinite(t1f) or not t1f > 0:
        raise ValueError(f"t1 must be a positive, finite scalar, got {t1f}")
    t1f = float(t1f)
    if substeps is not None and not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    if not (isinstance(max_impacts, int) and max_impacts >= 1):
        raise ValueError(f"max_impacts must be a positive integer, got {max_impacts!r}")
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(val, (int, float)) and val > 0):
            raise ValueError(f"{name} must be a positive number, got {val!r}")
    if dt is not None and not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    N, members, table, free = _resolve(structure, excitation, scale, r, u0, v0, record)
    if substeps is None:
        substeps = 1 if (free or method != "rk4") else 4  # dopri5 chooses its own steps
    dtype = jnp.result_type(structure.B)
    if method == "diffrax" and dtype != jnp.float64:
        raise ValueError(f"method 'diffrax' runs in float64; this structure is {dtype}: use "
                         "method='rk4' or 'dopri5' for float32")

    # the grid: the record's samples, or dt for a free vibration
    if free:
        dt_rec = min(t1f / 4000, 0.01) if dt is None else float(dt)
        table = np.zeros((1, 2))
    else:
        if dt is not None:
            raise ValueError(
                "dt applies to a free vibration; a ground motion is integrated on "
                "its record's samples (use substeps to refine)"
            )
        dt_rec = float(np.asarray(excitation.dt))
    n_steps = int(math.ceil(t1f / dt_rec - 1e-9))
    grid = np.minimum(np.arange(n_steps + 1) * dt_rec, t1f)
    if ts is not None:
        if summary_only:
            raise ValueError("ts applies to full responses, not with summary_only=True")
        tsn = np.asarray(ts, dtype=float)
        if tsn.ndim != 1 or tsn.size < 1 or not np.all(np.isfinite(tsn)):
            raise ValueError("ts must be a 1-D array of finite output times")
        if tsn.size > 1 and not np.all(np.diff(tsn) > 0):
            raise ValueError("ts must be strictly increasing")
        if tsn[0] < 0 or tsn[-1] > t1f * (1 + 1e-12):
            raise ValueError(f"ts must lie within [0, t1] = [0, {t1f}]")
    if not free:
        n_tab = max(table.shape[1], n_steps + 2)
        table = np.concatenate([table, np.zeros((table.shape[0], n_tab - table.shape[1]))], 1)

    n_dev = len(jax.local_devices()) if devices is None else int(devices)
    if not 1 <= n_dev <= len(jax.local_devices()):
        raise ValueError(
            f"devices must be between 1 and {len(jax.local_devices())}, got {devices!r}"
        )
    n_out = len(grid) if ts is None else len(ts)
    if chunk_size is None:
        if summary_only:
            chunk_size = 8192
        else:
            chunk_size = max(1, min(8192, int(2**28 // (16 * (n_out + max_impacts)))))
    if not (isinstance(chunk_size, int) and chunk_size >= 1):
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    chunk = min(chunk_size, N)
    chunk = n_dev * math.ceil(chunk / n_dev)
    n_chunks = math.ceil(N / chunk)
    if max_pieces is None:
        # a settling rigid block (housner) has many impacts per step; others a few at most
        max_pieces = (32 if model.rigid else 4) if method == "rk4" else 4096
    if not (isinstance(max_pieces, int) and max_pieces >= 2):
        raise ValueError(f"max_pieces must be an integer >= 2, got {max_pieces!r}")

    batched_names = [k for k, v in members.items() if np.ndim(v) == 1 and np.shape(v)[0] != 1]
    batched_names += [
        k
        for k in _FIELDS
        if np.ndim(getattr(structure, k)) == 1 and np.shape(getattr(structure, k))[0] != 1
    ]
    values = dict(members)
    values.update({k: getattr(structure, k) for k in _FIELDS})
    shared = {}
    for k, v in values.items():
        if k in batched_names:
            continue
        a = np.asarray(v)
        a = a.reshape(()) if a.size == 1 else a
        shared[k] = jnp.asarray(a, jnp.int32 if k == "record" else dtype)
    if not batched_names:  # one run: still batch of N = 1 through the same code
        batched_names = ["u0"]
        values["u0"] = np.reshape(np.asarray(values["u0"]), (1,))
        shared.pop("u0")

    if method == "diffrax":
        from ._simulate import _Config, _default_solver

        dcfg = _Config(
            model=model,
            impact=impact,
            solver=_default_solver(),
            rtol=float(rtol),
            atol=float(atol),
            max_steps=16384,
            max_impacts=max_impacts,
            adjoint="forward",
            use_jump_ts=True,
            dt=None,
        )
        ts_d = grid if ts is None else np.asarray(ts, float)
    else:
        fcfg = _fast.FastConfig(
            model=model,
            impact=impact,
            method="fixed" if method == "rk4" else "adaptive",
            substeps=substeps,
            n_steps=n_steps,
            free=free,
            full=not summary_only,
            max_impacts=max_impacts,
            max_pieces=max_pieces,
            rtol=float(rtol),
            atol=float(atol),
        )
    table_j = jnp.asarray(table, dtype)
    bar = _progress(N, progress if progress is not None else n_chunks > 1, f"{method} batch")
    parts = []
    try:
        for i in range(n_chunks):
            lo = i * chunk
            idx = np.minimum(np.arange(lo, lo + chunk), N - 1)  # pad the last chunk
            batched = {}
            for k in batched_names:
                a = np.asarray(values[k])[idx]
                batched[k] = jnp.asarray(a, jnp.int32 if k == "record" else dtype)
            if method == "diffrax":
                res = _diffrax_chunk_jit(
                    batched,
                    shared,
                    table_j,
                    jnp.asarray(dt_rec, dtype),
                    jnp.asarray(t1f, dtype),
                    jnp.asarray(ts_d, dtype),
                    dcfg,
                    free,
                )
                out = dict(
                    peak_u=res.peak_u,
                    n_impacts=res.n_impacts,
                    status=res.status,
                    t_overturn=res.t_overturn,
                )
                if not summary_only:
                    out.update(u=res.u, v=res.v, impact_times=res.impact_times)
            else:
                out = _fast_chunk_jit(
                    batched,
                    shared,
                    table_j,
                    jnp.asarray(dt_rec, dtype),
                    jnp.asarray(t1f, dtype),
                    fcfg,
                    n_dev,
                )
            n_keep = min(chunk, N - lo)
            parts.append(jax.tree_util.tree_map(lambda x: np.asarray(x)[:n_keep], out))
            if bar is not None:
                bar.update(n_keep)
    finally:
        if bar is not None:
            bar.close()
    res = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    rigid = model.rigid
    s_ns = structure
    peak = jnp.asarray(res["peak_u"])
    summary = Summary(
        peak_u=peak,
        peak_uplift=_per_member(lambda st, p: uplift(st, p, rigid=rigid), s_ns, peak, N),
        n_impacts=jnp.asarray(res["n_impacts"]),
        status=jnp.asarray(res["status"]),
        t_overturn=jnp.asarray(res["t_overturn"]),
    )
    if summary_only:
        return summary
    u, v = res["u"], res["v"]
    if method != "diffrax":
        if ts is not None:
            u, v = _hermite_resample(grid, u, v, np.asarray(ts, float))
            out_ts = np.asarray(ts, float)
        else:
            out_ts = grid
    else:
        out_ts = ts_d
    u = jnp.asarray(u)
    return Response(
        ts=jnp.asarray(out_ts),
        u=u,
        v=jnp.asarray(v),
        theta=_per_member(lambda st, x: theta_from_u(st, x, rigid=rigid), structure, u, N),
        uplift=_per_member(lambda st, x: uplift(st, x, rigid=rigid), structure, u, N),
        impact_times=jnp.asarray(res["impact_times"]),
        n_impacts=summary.n_impacts,
        peak_u=summary.peak_u,
        peak_uplift=summary.peak_uplift,
        status=summary.status,
        t_overturn=summary.t_overturn,
    )


def _per_member(fn, structure, x, N):
    """fn(structure, x) with structure fields of shape (N,) lined up with x's first axis."""
    fields = {}
    for k in _FIELDS:
        a = jnp.asarray(getattr(structure, k))
        if a.ndim == 1 and a.shape[0] == N and N != 1:
            a = a.reshape((N,) + (1,) * (x.ndim - 1))
        fields[k] = a
    return fn(RockingStructure(**fields), x)


def _hermite_resample(grid, u, v, ts):
    """Cubic Hermite interpolation of (u, v) from the grid to ts (last axis)."""
    i = np.clip(np.searchsorted(grid, ts, side="right") - 1, 0, len(grid) - 2)
    dtype = u.dtype
    h = (grid[i + 1] - grid[i]).astype(dtype)
    s = ((ts - grid[i]) / (grid[i + 1] - grid[i])).astype(dtype)
    uu, du = _fast._hermite(u[..., i], v[..., i] * h, u[..., i + 1], v[..., i + 1] * h, s)
    return uu, du / h


_run_jit = eqx.filter_jit(_fast.run)


def simulate_fast(
    structure,
    excitation,
    t1,
    ts,
    r,
    *,
    model,
    impact,
    method,
    substeps,
    dt,
    rtol,
    atol,
    max_impacts,
    max_pieces,
):
    """One run of the fast integrator, traceable (for `rockjax.simulate(method=...)`)."""
    free = isinstance(excitation, FreeVibration)
    if not free and not isinstance(excitation, GroundMotion):
        raise ValueError("method 'rk4'/'dopri5' supports FreeVibration and GroundMotion")
    if substeps is None:
        substeps = 1 if (free or method != "rk4") else 4  # dopri5 chooses its own steps
    if isinstance(t1, jax.core.Tracer):
        raise ValueError("t1 must be a concrete number with method 'rk4' or 'dopri5'")
    t1f = float(np.max(np.asarray(t1)))
    dtype = jnp.result_type(structure.B)
    if free:
        dt_rec = min(t1f / 4000, 0.01) if dt is None else float(dt)
        table = jnp.zeros((1, 2), dtype)
        scale = jnp.ones((), dtype)
    else:
        if isinstance(excitation.dt, jax.core.Tracer):
            raise ValueError("the record's dt must be concrete with method 'rk4' or 'dopri5'")
        if dt is not None:
            raise ValueError(
                "dt applies to a free vibration; a ground motion is integrated "
                "on its record's samples (use substeps to refine)"
            )
        dt_rec = float(np.asarray(excitation.dt))
        scale = excitation.scale
    n_steps = int(math.ceil(t1f / dt_rec - 1e-9))
    if not free:
        acc = jnp.asarray(excitation.accel, dtype)
        pad = max(0, n_steps + 2 - acc.shape[-1])
        table = jnp.concatenate([acc, jnp.zeros((pad,), dtype)])[None]
    grid = np.minimum(np.arange(n_steps + 1) * dt_rec, t1f)
    u0, v0 = excitation.initial_state()
    cfg = _fast.FastConfig(
        model=get_model(model),
        impact=impact,
        method="fixed" if method == "rk4" else "adaptive",
        substeps=substeps,
        n_steps=n_steps,
        free=free,
        full=True,
        max_impacts=max_impacts,
        max_pieces=((32 if get_model(model).rigid else 4) if method == "rk4" else 4096)
        if max_pieces is None else max_pieces,
        rtol=float(rtol),
        atol=float(atol),
    )
    out = _run_jit(
        structure,
        table,
        jnp.zeros((1,), jnp.int32),
        jnp.asarray(dt_rec, dtype),
        jnp.asarray(scale, dtype),
        jnp.reshape(jnp.asarray(u0, dtype), (1,)),
        jnp.reshape(jnp.asarray(v0, dtype), (1,)),
        jnp.asarray(r, dtype),
        jnp.asarray(t1f, dtype),
        cfg,
    )
    u, v = out["u"][:, 0], out["v"][:, 0]
    ts_n = grid if ts is None else np.asarray(ts, float)
    if ts is not None and not (ts_n.shape == grid.shape and np.array_equal(ts_n, grid)):
        u, v = _hermite_resample(grid, u, v, ts_n)
    rigid = cfg.model.rigid
    peak = out["peak_u"][0]
    return Response(
        ts=jnp.asarray(ts_n, dtype),
        u=u,
        v=v,
        theta=theta_from_u(structure, u, rigid=rigid),
        uplift=uplift(structure, u, rigid=rigid),
        impact_times=out["impact_times"][0],
        n_impacts=out["n_impacts"][0],
        peak_u=peak,
        peak_uplift=uplift(structure, peak, rigid=rigid),
        status=out["status"][0],
        t_overturn=out["t_overturn"][0],
    )
