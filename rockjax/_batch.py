r"""Batches of simulations: `rockjax.simulate_batch`, chunked, sharded and with progress.

Every model runs on three integrators (`rockjax.integrators`, passed as `integrator=`):

- `RK4()` (default): the batched stepper, classical RK4 on the record's grid (`substeps`
  per record interval) with every event located inside its step;
- `Dopri5()`: the same loop with Dormand–Prince 5(4) steps under error control (`rtol`,
  `atol`), for a full time history at a set tolerance;
- `EventRestart()`: the event-restart diffrax solve under `jax.vmap`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._checks import (
    check_end_time,
    check_float64,
    check_scene,
    check_ts,
    stepper_grid_step,
)
from ._config import ensure_x64
from ._devices import advise_configure
from ._errors import ParameterError
from ._excitation import FreeVibration, GroundMotion, RecordTable
from ._execution import Execution
from ._fidelity import warn_sdof_lift_off
from ._records import common_time_step, on_grid, Record
from ._response import Response
from ._status import STATUS_NAMES
from ._structure import FIELDS, RockingStructure
from .integrators import (
    AbstractIntegrator,
    Dopri5,
    EventRestart,
    from_keywords,
    resample_outputs,
    RK4,
    run,
    solve,
)
from .models import get_model

METHODS = ("rk4", "dopri5", "diffrax")
#: `simulate_batch`'s integrator for each `method=` of the keyword form: `RK4` by default,
#: `Dopri5` and `EventRestart` (forward mode, as batches need no reverse gradient) at
#: rtol 1e-8, atol 1e-10
DEFAULT_INTEGRATORS = {
    "rk4": RK4(),
    "dopri5": Dopri5(rtol=1e-8, atol=1e-10),
    "diffrax": EventRestart(rtol=1e-8, atol=1e-10, adjoint="forward"),
}
#: free vibration [s] after each record's end when the records of a batch are a sequence
DEFAULT_TAIL = 5.0


class Summary(eqx.Module):
    """Per-member summaries of a batch (arrays of shape `(N,)`, SI units).

    `peak_u` [m] (peak |u| of the continuous solution), `peak_uplift` [m], `n_impacts`,
    `status` (0 completed, 1 overturned, 2 max_impacts, 3 solver_failure), `t_overturn`
    [s] (`inf` if it did not overturn) and `t_end` [s], the end of each member's run
    (`t1`, or with a sequence of records its record's end plus `tail`).
    """

    peak_u: jnp.ndarray
    peak_uplift: jnp.ndarray
    n_impacts: jnp.ndarray
    status: jnp.ndarray
    t_overturn: jnp.ndarray
    t_end: jnp.ndarray

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
            "t_end": np.asarray(self.t_end),
        }


def _length(name, x):
    """Batch length of an input: None for a scalar, n for shape (n,); else an error."""
    shape = np.shape(x)
    if len(shape) == 0:
        return None
    if len(shape) == 1:
        return shape[0]
    raise ParameterError(
        f"{name} must be a scalar or a 1-D array (one value per run), got shape {shape}",
        param=name
    )


def _records(excitation, record):
    """The record table (n_records, n_samples) [m/s²] and the per-member record index."""
    if np.ndim(excitation.dt) != 0:
        raise ParameterError(
            "the records of a batch must share one time step: dt must be a "
            "scalar (records of different time steps go in as a sequence, "
            "excitation=[record, ...])", param="excitation"
        )
    acc = np.asarray(excitation.accel)
    if acc.ndim == 1:
        acc = acc[None]
    elif acc.ndim != 2:
        raise ParameterError(
            f"accel must be 1-D (one record) or 2-D (records x samples), got shape {acc.shape}",
            param="excitation"
        )
    if record is None:
        record = 0 if acc.shape[0] == 1 else np.arange(acc.shape[0])
    rec = np.asarray(record)
    if not np.issubdtype(rec.dtype, np.integer) or np.any(rec < 0) or np.any(rec >= acc.shape[0]):
        raise ParameterError(
            f"record must hold integer indices into the {acc.shape[0]} "
            f"record(s) of excitation.accel, got {rec}", param="record"
        )
    return acc, rec


@dataclasses.dataclass(frozen=True)
class _Suite:
    """Records of any time steps on one grid: `table` (n_records, n) [m/s²] sampled every
    `dt` [s] (each record's samples kept, zero after its end), `lengths` its samples per
    record and `durations` [s] each record's end. With `steps` (record_steps="own"), row
    i keeps record i's own samples, every `steps[i]` [s], and `dt` is the largest step."""

    dt: float
    table: np.ndarray
    lengths: np.ndarray
    durations: np.ndarray
    steps: np.ndarray | None = None


def _suite_item(i, item):
    """(dt [s], samples [m/s²] times the GroundMotion's own scale, name) of one record."""
    if isinstance(item, Record):
        return item.dt, np.asarray(item.accel), item.source or f"record {i}"
    if not isinstance(item, GroundMotion):
        raise ParameterError(
            f"excitation: a sequence must hold Records or GroundMotions, item {i} is a "
            f"{type(item).__name__}", param="excitation"
        )
    if np.ndim(item.dt) != 0 or np.ndim(item.accel) != 1 or np.ndim(item.scale) != 0:
        raise ParameterError(
            f"excitation: GroundMotion {i} of the sequence must hold one record (scalar dt "
            "and scale, 1-D accel)", param="excitation"
        )
    if np.any(np.asarray(item.u0) != 0) or np.any(np.asarray(item.v0) != 0):
        raise ParameterError(
            f"excitation: GroundMotion {i} of the sequence has u0 or v0; pass u0=, v0= to "
            "simulate_batch instead", param="excitation"
        )
    return float(item.dt), np.asarray(item.accel) * float(item.scale), f"record {i}"


def _make_suite(items, record_steps="common"):
    """The records of a sequence, resampled exactly onto their common time step (or each
    kept on its own step: record_steps="own")."""
    if len(items) == 0:
        raise ParameterError("excitation: the sequence of records is empty", param="excitation")
    dts, accels, names = zip(*(_suite_item(i, x) for i, x in enumerate(items)))
    own = record_steps == "own"
    step = max(dts) if own else common_time_step(dts, names=names)
    grids = list(accels) if own else [on_grid(a, int(round(d / step))) for d, a in zip(dts, accels)]
    lengths = np.array([g.size for g in grids])
    table = np.zeros((len(grids), int(lengths.max())))
    for i, g in enumerate(grids):
        table[i, : g.size] = g
    durations = np.array([d * (a.size - 1) for d, a in zip(dts, accels)])
    return _Suite(dt=step, table=table, lengths=lengths, durations=durations,
                  steps=np.array(dts, float) if own else None)


def _suite_ends(suite, record, t1, tail):
    """Each member's end [s]: its record's end plus `tail`, capped at `t1` when given."""
    if tail is None:
        tail = DEFAULT_TAIL
    tl = np.asarray(tail, dtype=float) if np.ndim(tail) == 0 else None
    if tl is None or not np.isfinite(tl) or tl < 0:
        raise ParameterError(f"tail must be a finite number of seconds >= 0, got {tail!r}",
                             param="tail")
    ends = suite.durations[np.asarray(record)] + float(tl)
    return ends if t1 is None else np.minimum(ends, check_end_time(t1))


def _suite_members(suite, scale, record, t1, tail):
    """scale, record and t_end of a sequence of records."""
    n = suite.table.shape[0]
    if record is None:
        record = 0 if n == 1 else np.arange(n)
    rec = np.asarray(record)
    if not np.issubdtype(rec.dtype, np.integer) or np.any(rec < 0) or np.any(rec >= n):
        raise ParameterError(
            f"record must hold integer indices into the {n} record(s) of the sequence, "
            f"got {rec}", param="record"
        )
    if rec.ndim > 1:
        raise ParameterError(f"record must be a scalar or a 1-D array, got shape {rec.shape}",
                             param="record")
    t_end = _suite_ends(suite, rec, t1, tail)
    if t_end.ndim == 1 and np.all(t_end == t_end[0]):
        t_end = t_end[:1]  # one end for all: the stepper needs no per-member ends
    own = {} if suite.steps is None else {"dt_rec": suite.steps[rec]}  # each on its own grid
    return {"scale": 1.0 if scale is None else scale, "record": rec, "t_end": t_end, **own}


def _batch_length(structure, members):
    """N: the common length of every batched input (1 if none is batched)."""
    lengths = {}
    for name, x in [*members.items(), *((k, getattr(structure, k)) for k in FIELDS)]:
        n = _length(name, x)
        if n is not None and n != 1:
            lengths[name] = n
    sizes = set(lengths.values())
    if len(sizes) > 1:
        detail = ", ".join(f"{k}: {v}" for k, v in lengths.items())
        raise ValueError(
            f"batched inputs must all have the same length ({detail}); build the "
            "combinations first, e.g. with numpy.meshgrid"
        )
    return sizes.pop() if sizes else 1


def _resolve(structure, excitation, scale, r, u0, v0, record, t1, tail, record_steps):
    """The batch: N, each per-member input as a scalar or an (N,) array, the record table,
    whether it is a free vibration, and the suite (a sequence of records) or None."""
    seq = isinstance(excitation, (list, tuple))
    suite = _make_suite(excitation, record_steps) if seq else None
    if record_steps != "common" and (record_steps != "own" or not seq):
        raise ValueError(f"record_steps must be 'common' or 'own' (with a sequence of "
                         f"records), got {record_steps!r}")
    if suite is None:
        check_scene(structure, excitation)
        if tail is not None:
            raise ParameterError(
                "tail applies to a sequence of records (excitation=[record, ...]); a "
                "single excitation runs to t1", param="tail"
            )
    elif not isinstance(structure, RockingStructure):
        raise ParameterError(
            f"structure must be a RockingStructure, got {type(structure).__name__}",
            param="structure")
    free = isinstance(excitation, FreeVibration)
    members = {
        "u0": excitation.u0 if u0 is None and suite is None else (0.0 if u0 is None else u0),
        "v0": excitation.v0 if v0 is None and suite is None else (0.0 if v0 is None else v0),
    }
    if suite is not None:
        members.update(_suite_members(suite, scale, record, t1, tail))
        table = suite.table
    elif free:
        if scale is not None or record is not None:
            raise ParameterError("scale and record apply to a GroundMotion, not a FreeVibration",
                                 param="scale")
        members.update(scale=1.0, record=0, t_end=check_end_time(t1))
        table = None
    else:
        members["scale"] = excitation.scale if scale is None else scale
        table, members["record"] = _records(excitation, record)
        members["t_end"] = check_end_time(t1)
    members["r"] = structure.restitution if r is None else r
    N = _batch_length(structure, members)
    for name, x in members.items():
        a = np.asarray(x)
        if name != "record" and not np.all(np.isfinite(a)):
            raise ParameterError(f"{name} must be finite, got {a}", param=name)
    rr = np.asarray(members["r"])
    if np.any(rr < 0) or np.any(rr > 1):
        raise ParameterError(f"r must lie in [0, 1], got {rr}", param="r")
    return N, members, table, free, suite


@functools.cache
def _mesh(n_devices):
    devices = np.array(jax.local_devices()[:n_devices])
    return jax.sharding.Mesh(devices, ("batch",))


class _Batch(eqx.Module):
    """A batch as the integrators take it: a `RockingStructure` and a `RecordTable` whose
    per-member leaves have shape (N,) (one value per member) or () (shared), the
    coefficient of restitution `r` and each member's end `t_end` [s], likewise."""

    structure: RockingStructure
    excitation: RecordTable
    r: jnp.ndarray
    t_end: jnp.ndarray

    def member_leaves(self):
        """The same tree with True at the leaves that vary per member (shape (N,))."""
        exc = self.excitation
        per = lambda x: jnp.ndim(x) == 1  # noqa: E731
        table = jax.tree_util.tree_map(lambda _: False, exc)
        table = eqx.tree_at(lambda e: [getattr(e, k) for k in exc.MEMBER_FIELDS], table,
                            [per(getattr(exc, k)) for k in exc.MEMBER_FIELDS])
        return _Batch(structure=jax.tree_util.tree_map(per, self.structure),
                      excitation=table, r=per(self.r), t_end=per(self.t_end))


def _stepper_chunk(model, batched, shared, cfg, n_devices):
    """Run one chunk on the batched stepper, split over `n_devices` local devices."""

    def kernel(batched):
        b = eqx.combine(batched, shared)
        return run(model, b.structure, b.excitation, b.r, b.t_end, cfg)

    if n_devices == 1:
        return kernel(batched)
    P = jax.sharding.PartitionSpec
    # shard_map, not automatic partitioning: each device runs its own loop, and the
    # "does any member need another piece" tests stay local (no cross-device sync per step)
    f = jax.shard_map(kernel, mesh=_mesh(n_devices), in_specs=(P("batch"),),
                      out_specs=P("batch"), check_vma=False)
    return f(batched)


def _diffrax_chunk(model, batched, shared, ts, cfg):
    """Run one chunk through the event-restart integrator under `jax.vmap`: each member
    a one-run `RecordTable` (its record's row of the shared table, zero past its end)."""

    def one(member):
        b = eqx.combine(member, shared)
        return solve(model, b.structure, b.excitation, b.t_end, ts, b.r, cfg)

    return jax.vmap(one)(batched)


_stepper_chunk_jit = eqx.filter_jit(_stepper_chunk)
_diffrax_chunk_jit = eqx.filter_jit(_diffrax_chunk)


def _progress(total, enabled, desc):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, leave=False)


@dataclasses.dataclass(frozen=True)
class _Plan:
    """What a batch runs: the model, its grid and the integrator's settings."""

    model: object
    method: str
    free: bool
    dt_rec: float
    t1: float
    grid: np.ndarray
    cfg: object
    n_devices: int
    chunk: int


def _batch_inputs(structure, members, table, lengths, plan, N, dtype):
    """The batch as one `_Batch` pytree: every per-member input an (N,) array if it varies
    per member, else a scalar (shared: not copied into every member). With no input
    varying, `u0` gets shape (1,), so one run goes through the same code as N."""

    def member(x, kind=dtype):
        a = np.asarray(x)
        if a.ndim == 1 and a.shape[0] == N and N > 1:
            return jnp.asarray(a, kind)
        return jnp.asarray(a.reshape(()) if a.size == 1 else a, kind)

    u0 = member(members["u0"])
    if N == 1:
        u0 = u0.reshape((1,))
    excitation = RecordTable(
        table=jnp.asarray(table, dtype),
        lengths=jnp.asarray([2] if lengths is None else lengths, jnp.int32),
        dt=member(members.get("dt_rec", plan.dt_rec)), record=member(members["record"],
                                                                      jnp.int32),
        scale=member(members["scale"]), u0=u0, v0=member(members["v0"]), free=plan.free,
    )
    return _Batch(structure=jax.tree_util.tree_map(member, structure), excitation=excitation,
                  r=member(members["r"]), t_end=member(members["t_end"]))


def _run_chunks(plan, N, batch, ts_d, progress):
    """Every chunk through its compiled kernel (the last padded), with a progress bar."""
    n_chunks = math.ceil(N / plan.chunk)
    auto = n_chunks > 1 and sys.stderr.isatty()  # no carriage returns in logs
    bar = _progress(N, progress if progress is not None else auto, f"{plan.method} batch")
    varying, shared = eqx.partition(batch, batch.member_leaves())
    parts = []
    try:
        for i in range(n_chunks):
            lo = i * plan.chunk
            idx = np.minimum(np.arange(lo, lo + plan.chunk), N - 1)  # pad the last chunk
            chunk = jax.tree_util.tree_map(lambda x: x[idx], varying)
            if plan.method == "diffrax":
                out = _diffrax_chunk_jit(plan.model, chunk, shared, ts_d, plan.cfg)
            else:
                out = _stepper_chunk_jit(plan.model, chunk, shared, plan.cfg, plan.n_devices)
            n_keep = min(plan.chunk, N - lo)
            parts.append(jax.tree_util.tree_map(lambda x: np.asarray(x)[:n_keep], out))
            if bar is not None:
                bar.update(n_keep)
    finally:
        if bar is not None:
            bar.close()
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def simulate_batch(
    structure,
    excitation,
    t1=None,
    *,
    scale=None,
    r=None,
    record=None,
    tail=None,
    model="simplified",
    integrator: AbstractIntegrator | None = None,
    ts=None,
    summary_only=False,
    execution: Execution | None = None,
    **keywords,
):
    r"""Many simulations of Eq. 1 at once: any mix of structures, r, scales, records and
    initial states.

    Each batched input is a 1-D array with one value per run (all of the same length N);
    scalars are shared. Batched inputs are the fields of `structure` (e.g.
    `structure.replace(k_f=np.linspace(...))`), of `excitation` (`scale`, `u0`, `v0` of a
    `GroundMotion` or `FreeVibration`, e.g. `FreeVibration(u0=np.linspace(...))`) and the
    arguments `scale`, `r` and `record`.

    Several records, of any time steps and lengths, go in as a sequence
    `excitation=[record, ...]` of `rockjax.Record`s or single-record `GroundMotion`s (whose
    own `scale` multiplies their samples), and `record` picks one per run (default: one run
    per record). They are resampled exactly onto their common time step
    (`rockjax.common_time_step`: 0.005, 0.01 and 0.02 s give 0.005 s; linear
    interpolation keeps every sample, so the piecewise-linear forcing is unchanged), and
    each run ends at its own record's end plus `tail`: after that nothing counts (no
    impacts, peaks or status from the padding that the longer records need). Inside, every
    batch becomes one `rockjax.RecordTable` (the records as one table, and per run its
    record, scale and initial state), the form every integrator consumes.

    **Arguments:**

    - `structure`: a `RockingStructure` (SI units), its fields scalars or (N,) arrays.
    - `excitation`: a `GroundMotion`, a `FreeVibration`, a `rockjax.Record`, or a sequence
      of records (above). Several records of one time step may also go in one
      `GroundMotion` with `accel` of shape (n_records, n_samples), zero-padded, with one
      `t1` for all (the padding then counts as ground motion at rest).
    - `t1` [s]: the end time. Required for one `GroundMotion` or `FreeVibration`; with a
      sequence of records it caps each run's end (default: no cap).
    - `scale`: factors on the ground acceleration (default the excitation's own `scale`).
    - `r`: the coefficient of restitution (default the structure's, Eq. 3).
    - `record`: the index of each run's record (default: one run per record).
    - `tail` [s]: with a sequence of records, the free vibration after each record's end
      (default `DEFAULT_TAIL` = 5 s; the paper's impact rule counts every crossing of
      u = 0, so the free rocking of the tail adds about 7 impacts per second for the
      Table 1 column). `Summary.t_end` gives each run's end.
    - `model`: as `rockjax.simulate`: a name of the fidelity ladder, a restoring-force law
      or a model object (an impact rule other than the paper's goes on the model:
      `rockjax.models.get_model("simplified", "after_uplift")`); every model runs on every
      integrator, the 2-DOF body (`"two_spring_2dof"`) included.
    - `integrator`: an object of `rockjax.integrators` holding its settings.
      `RK4(substeps=...)` (default `RK4()`): fixed steps of the record's dt / `substeps`
      (default 4; for a free vibration steps of `dt`, default min(t1 / 4000, 10 ms), which
      is also the output grid) with events located inside each step, the fast path;
      accuracy against speed: the peak-u error falls about 16x per halving of the step;
      on El Centro x1.0 it is about 1e-5, 1e-6, 1e-7 for `substeps` 1, 2, 4, and over
      scales 0.1-2.0 (near overturning the response is more sensitive) at worst 1e-3,
      3e-4, 2e-5 (`benchmarks/results.md`); `max_pieces`, event-localised pieces per
      step, defaults from the model (4, 32 for the rigid `housner` model, whose settling
      impacts crowd, 8 for the 2-DOF body). `Dopri5(rtol=..., atol=...)`: adaptive
      Dormand–Prince 5(4) steps inside the same loop (`substeps` then only caps the step).
      `EventRestart(...)`: `rockjax.simulate`'s default under `vmap` (every member waits
      for the slowest).
    - `ts` [s]: output times (full responses only). Fast methods compute the response on
      their grid and interpolate (cubic Hermite) to `ts`.
    - `summary_only`: return a `Summary` (peak_u, peak_uplift, n_impacts, status,
      t_overturn, t_end) and store no time history.
    - `execution`: a `rockjax.Execution`: chunk size, devices, progress bar and the
      records' grid, which change how the batch runs but not its results.
    - `**keywords`: the keyword form of earlier versions, still accepted: `u0=`, `v0=`
      (they override the excitation's), `impact=` (the model's impact rule),
      `chunk_size=`, `devices=`, `progress=`, `record_steps=` (the `Execution`'s),
      `fidelity_warning=False` (else filter `rockjax.FidelityWarning` with `warnings`:
      one warning per batch, counting the runs that lift off by more than 3 u_crit under
      the paper's SDOF models), and `method=` (`"rk4"`, `"dopri5"`, `"diffrax"`) with
      `substeps`, `dt`, `rtol`, `atol`, `max_impacts`, `max_pieces` (and `simulate`'s
      `solver`, `max_steps`, `adjoint`, `jump_ts`): they build the integrator
      (`"dopri5"` and `"diffrax"` at rtol 1e-8, atol 1e-10); one that contradicts
      `integrator=` raises `ValueError` naming it.

    **Returns:** a `Summary`, or a `Response` whose arrays have a leading batch axis of
    length N (`impact_times` has shape (N, max_impacts)); on the grid past a run's own end
    its state is held. Failures come back per member as `status`, never as NaN.

    **Gradients:** a batch is planned on concrete values (its chunks, grid and devices),
    so `jax.grad` cannot trace through it: a traced input raises a `ParameterError`
    naming it. Differentiate `rockjax.simulate` (under `jax.vmap` for many runs) instead.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    gm = rockjax.GroundMotion.from_file("IELC180.AT2", units="g")
    out = rockjax.simulate_batch(s, gm, 40.0, scale=np.linspace(0.1, 2.0, 10_000),
                                 summary_only=True)
    out.peak_u, out.status
    # records of 0.01 and 0.02 s, each to its end + 5 s, at two scales
    recs = [rockjax.read_record("IELC180.AT2"), rockjax.read_record("elCentro.AT2")]
    out = rockjax.simulate_batch(s, recs, record=[0, 1, 0, 1], scale=[1, 1, 2, 2],
                                 summary_only=True)
    out.t_end                                          # [45.0, 36.16, 45.0, 36.16]
    ```
    """
    ensure_x64()
    execution = Execution.from_keywords(execution, keywords)
    u0, v0 = keywords.pop("u0", None), keywords.pop("v0", None)
    fidelity_warning = keywords.pop("fidelity_warning", True)
    model = get_model(model, keywords.pop("impact", "paper"))
    method = keywords.get("method")
    if method is not None and method not in METHODS:
        raise ParameterError(f"method must be one of {METHODS}, got {method!r}", param="method")
    integrator = from_keywords(integrator, keywords, defaults=DEFAULT_INTEGRATORS,
                               default="rk4", where="simulate_batch")
    _refuse_tracers(structure=structure, excitation=excitation, t1=t1, scale=scale, r=r,
                    u0=u0, v0=v0, record=record, tail=tail, ts=ts)
    if isinstance(excitation, Record):  # one record, e.g. rockjax.datasets.el_centro()
        excitation = GroundMotion.from_record(excitation)
    record_steps = execution.record_steps
    N, members, table, free, suite = _resolve(structure, excitation, scale, r, u0, v0, record,
                                              t1, tail, record_steps)
    if record_steps == "own" and (not summary_only or integrator.method == "diffrax"):
        raise ValueError('record_steps="own" runs summaries only (summary_only=True) on '
                         '"rk4" or "dopri5"')
    t_last = float(np.max(members["t_end"]))
    dtype = jnp.result_type(structure.B)
    check_float64(integrator.method, dtype)
    check_ts(ts, t_last, summary_only)
    # each record's samples: the ground acceleration is zero after the last one
    lengths = None if free else (suite.lengths if suite is not None else
                                 np.full(table.shape[0], table.shape[1]))
    ends = None if suite is None or suite.steps is None else _suite_ends(  # every record's
        suite, np.arange(len(suite.steps)), t1, tail)
    dt_rec, grid, table = _grid(excitation if suite is None else suite, table, free, t_last,
                                integrator.dt, ends)
    if execution.devices is None:
        advise_configure()
    n_dev = _devices(execution.devices)
    n_out = len(grid) if ts is None else len(ts)
    chunk = _chunk(execution.chunk_size, summary_only, n_out, integrator.max_impacts, N, n_dev)
    plan = _Plan(
        model=model, method=integrator.method, free=free, dt_rec=dt_rec, t1=t_last,
        grid=grid, cfg=integrator.config(model, forced=not free, n_steps=len(grid) - 1,
                                         full=not summary_only),
        n_devices=n_dev, chunk=chunk,
    )
    batch = _batch_inputs(structure, members, table, lengths, plan, N, dtype)
    ts_d = jnp.asarray(grid if ts is None else np.asarray(ts, float), dtype)
    res = _run_chunks(plan, N, batch, ts_d, execution.progress)
    t_end = np.broadcast_to(np.asarray(members["t_end"], float), (N,))
    out = _assemble(plan, res, structure, N, ts, summary_only, t_end)
    warn_sdof_lift_off(model, structure, not free, out.peak_u, fidelity_warning)
    return out


def _refuse_tracers(**inputs):
    """A clear error for `jax.grad`/`jax.jit` through a batch (planned on concrete values)."""
    for name, x in inputs.items():
        if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(x)):
            raise ParameterError(
                f"{name} is a JAX tracer: simulate_batch plans its chunks, grid and devices "
                "on concrete values, so jax.grad, jax.jit and jax.vmap cannot trace through "
                "it; differentiate rockjax.simulate instead (jax.vmap it for many runs, "
                "integrator=rockjax.integrators.RK4() for the batch's fast path)", param=name)


def _grid(excitation, table, free, t1f, dt, ends=None):
    """(step [s], the grid [s], the record table padded past t1): the record's samples,
    the common step of a suite, or dt for a free vibration. `ends` [s]: with records on
    their own steps, the end of a run of each record (the longest run sets the steps)."""
    if isinstance(excitation, _Suite):
        if dt is not None:
            raise ParameterError(
                "dt applies to a free vibration; a sequence of records is integrated on "
                "their common time step (use substeps to refine)", param="dt"
            )
        dt_rec, n_steps = excitation.dt, int(math.ceil(t1f / excitation.dt - 1e-9))
        if ends is not None:
            n_steps = int(np.max(np.ceil(ends / excitation.steps - 1e-9)))
    else:
        dt_rec, n_steps = stepper_grid_step(excitation, t1f, dt)
    grid = np.minimum(np.arange(n_steps + 1) * dt_rec, t1f)
    if free:
        return dt_rec, grid, np.zeros((1, 2))
    n_tab = max(table.shape[1], n_steps + 2)
    table = np.concatenate([table, np.zeros((table.shape[0], n_tab - table.shape[1]))], 1)
    return dt_rec, grid, table


def _devices(devices):
    n_dev = len(jax.local_devices()) if devices is None else int(devices)
    if not 1 <= n_dev <= len(jax.local_devices()):
        raise ParameterError(
            f"devices must be between 1 and {len(jax.local_devices())}, got {devices!r}",
            param="devices"
        )
    return n_dev


def _chunk(chunk_size, summary_only, n_out, max_impacts, N, n_dev):
    """Runs per compiled call: at most 4096 summaries per device (the stepper's arrays of
    a few thousand members stay in cache: measured faster per run than 5,000 or 10,000), or
    as many full responses as fit in about 256 MB; the N runs split into equal chunks
    (10,000 runs on 2 devices: two of 5,000, not 8,192 and a padded 8,192), a multiple of
    the device count."""
    if chunk_size is None:
        if summary_only:
            chunk_size = 4096 * n_dev
        else:
            chunk_size = max(1, min(8192, int(2**28 // (32 * (n_out + max_impacts)))))
    if not (isinstance(chunk_size, int) and chunk_size >= 1):
        raise ParameterError(f"chunk_size must be a positive integer, got {chunk_size!r}",
                             param="chunk_size")
    equal = math.ceil(N / math.ceil(N / chunk_size))  # the fewest chunks, of equal size
    return n_dev * math.ceil(equal / n_dev)


def _per_member(fn, structure, x, N):
    """fn(structure, x) with structure fields of shape (N,) lined up with x's first axis."""

    def line_up(a):
        a = jnp.asarray(a)
        return a.reshape((N,) + (1,) * (x.ndim - 1)) if a.ndim == 1 and N != 1 else a

    return fn(jax.tree_util.tree_map(line_up, structure), x)


def _assemble(plan, res, structure, N, ts, summary_only, t_end):
    """A Summary, or a Response with a leading batch axis of length N."""
    peak_u = jnp.asarray(res["peak_u"])
    if plan.method != "diffrax":  # the stepper's peak is of the model's peak_coordinate
        peak_u = _per_member(plan.model.u_of_peak, structure, peak_u, N)
    peak_up = _per_member(lambda s, p: plan.model.peak_uplift(s, p, jnp.asarray(
        res["peak_uplift"])), structure, peak_u, N)
    summary = Summary(peak_uplift=peak_up, t_end=jnp.asarray(t_end, peak_u.dtype),
                      peak_u=peak_u, **{k: jnp.asarray(res[k]) for k in
                                        ("n_impacts", "status", "t_overturn")})
    if summary_only:
        return summary
    out = {k: res[k] for k in ("u", "v", "theta", "uplift", "impact_times")}
    out_ts = plan.grid if ts is None else np.asarray(ts, float)
    if plan.method != "diffrax" and ts is not None:
        out = resample_outputs(plan.model, plan.grid, out, out_ts, lambda u: _per_member(
            plan.model.theta_uplift_of_u, structure, jnp.asarray(u), N))
    return Response(ts=jnp.asarray(out_ts), **{k: jnp.asarray(v) for k, v in out.items()},
                    **{f.name: getattr(summary, f.name) for f in dataclasses.fields(summary)
                       if f.name != "t_end"})
