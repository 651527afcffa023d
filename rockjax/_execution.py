r"""How a batch runs (not what it computes): chunks, devices, progress, record grids."""

from __future__ import annotations

import dataclasses

from ._errors import ParameterError

RECORD_STEPS = ("common", "own")


@dataclasses.dataclass(frozen=True)
class Execution:
    r"""How `rockjax.simulate_batch` runs a batch; none of these changes its results.

    **Arguments:**

    - `chunk_size`: runs per compiled call (memory stays bounded); the last chunk is
      padded, so every chunk reuses one compilation. Default: 4096 summaries per device,
      or as many full responses as fit in about 256 MB.
    - `devices`: how many local devices to split each chunk over, from 1 to the number of
      local devices (default: all of `jax.local_devices()`; on a CPU
      `rockjax.configure()` makes one device per core, unless `XLA_FLAGS`,
      `JAX_NUM_CPU_DEVICES` or `ROCKJAX_CPU_DEVICES` say otherwise or JAX ran before it:
      docs/batches.md; without it, a batch on one CPU device of a multi-core machine warns
      once).
    - `progress`: show a tqdm bar on stderr (default None: when there is more than one
      chunk and stderr is a terminal, so logs get no carriage returns).
    - `record_steps`: with a sequence of records, `"common"` (default: every record
      resampled exactly onto their common time step) or `"own"`: each run on its own
      record's samples and step (records of unrelated steps, e.g. pulses of many periods:
      `overturning_spectrum`); summaries only, on `RK4` or `Dopri5`. The steps of the
      longest run over every record of the sequence fix the compiled program, so calls on
      the same records with other `record`/`scale` (and a `chunk_size` dividing N) reuse
      it.

    **Example:**

        >>> rockjax.Execution(chunk_size=512, progress=False)
        Execution(chunk_size=512, devices=None, progress=False, record_steps='common')
    """

    chunk_size: int | None = None
    devices: int | None = None
    progress: bool | None = None
    record_steps: str = "common"

    #: the keyword form of earlier versions: `simulate_batch(chunk_size=...)` and so on
    KEYWORDS = ("chunk_size", "devices", "progress", "record_steps")

    def __post_init__(self):
        v = self.chunk_size
        if v is not None and not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
            raise ParameterError(f"chunk_size must be a positive integer, got {v!r}",
                                 param="chunk_size")
        v = self.devices  # its upper bound, the local devices, is checked when a batch runs
        if v is not None and not (isinstance(v, int) and not isinstance(v, bool)):
            raise ParameterError(f"devices must be an integer, got {v!r}", param="devices")
        if self.progress not in (None, True, False):
            raise ParameterError(f"progress must be True, False or None, got "
                                 f"{self.progress!r}", param="progress")
        if self.record_steps not in RECORD_STEPS:
            raise ParameterError(f"record_steps must be one of {RECORD_STEPS}, got "
                                 f"{self.record_steps!r}", param="record_steps")

    @classmethod
    def from_keywords(cls, execution, keywords: dict) -> Execution:
        """`execution`, or one built from the keyword form (`chunk_size=`, `devices=`,
        `progress=`, `record_steps=`), popped from `keywords`; both at once is an error
        naming the keyword."""
        given = {k: keywords.pop(k) for k in cls.KEYWORDS if k in keywords}
        if execution is None:
            return cls(**given)
        if not isinstance(execution, cls):
            raise ParameterError(f"execution must be a rockjax.Execution, got "
                                 f"{type(execution).__name__}", param="execution")
        if given:
            name = next(iter(given))
            raise ParameterError(f"{name}= and execution= both given; set {name} on the "
                                 "Execution", param=name)
        return execution
