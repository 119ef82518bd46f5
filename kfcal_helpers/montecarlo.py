"""The Monte Carlo core shared by every course problem: seeds, chunks, threads, progress,
cancellation and the memory/time estimate.

A problem supplies an :class:`Experiment`: how to draw and filter one *chunk* of realizations
into partial sums (or per-run arrays), how to add those up, and what a chunk costs.  Subclassing
:class:`ArrayExperiment` gives the bookkeeping for a total of declared arrays (sums or per-run
arrays, their bytes counted from their shapes), so a problem writes ``arrays()``, ``run_chunk`` and
``result`` and states its measured costs.  The core (:func:`run`) does everything else, the same way
for every problem:

* **Seeds (one policy).**  The ``n_runs`` realizations are split into chunks of
  ``experiment.chunk_size()`` (a function of the problem's settings only, never of the machine or
  of ``workers``).  Chunk ``c`` draws from its own stream: for an int seed (or None, fresh
  entropy) ``numpy.random.Generator(numpy.random.PCG64DXSM(numpy.random.SeedSequence(seed).spawn(n_chunks)[c]))``,
  for a ``numpy.random.Generator`` ``seed.spawn(n_chunks)[c]`` (:func:`chunk_generators`).
  PCG64DXSM is numpy's recommended successor of ``default_rng``'s PCG64 (it draws normals about
  30 % faster).  :func:`chunk_generators` gives the same streams back, to redraw any realization.
* **Workers (threads, never processes).**  Up to ``workers`` chunks run at once on a thread pool
  (numpy releases the GIL in its array loops); the default is :func:`default_workers`.  Partial
  results are added in chunk order, so the result is the same, bit for bit, for any number of
  workers.  Threads exist on every operating system: nothing is forked or pickled.
* **Memory and time.**  :func:`estimate` adds up what the experiment says it needs (the fixed part,
  every chunk in flight, the statistics at the end) and refuses, with its estimate, a run whose
  peak exceeds :data:`MEMORY_LIMIT` or whose one-thread time exceeds :data:`MAX_SECONDS`, before
  any work starts.  Fewer chunks fly at once when more would not fit.  With two or more chunks in
  flight (on worker threads) the end's statistics are counted on top of them, because memory freed by
  a worker thread stays with that thread's allocator; one chunk at a time runs in the calling thread
  and the end reuses its memory (``peak = fixed + max(chunk, final)``).
* **Progress and cancellation.**  A progress bar over realizations (quiet under tests and CI,
  :mod:`kfcal_helpers.progress`).  An exception in the calling thread while chunks run
  (``KeyboardInterrupt`` from Ctrl-C, or whatever the command line raises on SIGTERM) cancels the
  chunks not started and stops the running ones at their next :meth:`Chunk.check` (which
  :meth:`Chunk.tick` calls); the exception then propagates.  **The one way to cancel**: a chunk
  calls ``chunk.check()`` between its expensive steps (or ``chunk.tick(n)``, which checks too) and
  nothing else: ``check()`` raises :class:`Cancelled`, which the core catches.  A chunk never tests
  ``chunk.cancelled`` to return early, so whatever ``run_chunk`` returns is a whole chunk and
  ``add`` never sees a partial one.

The results of every problem offer the interface :class:`kfcal_helpers.consistency.MonteCarloSummary`
(``n_runs``, ``alpha``, ``filter``, ``seconds``, ``checks()``), and :mod:`kfcal_helpers.consistency`
builds every band.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass
from functools import partial
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .progress import progress_bar
from .validation import (MAX_COUNT, checked, optional, require_bool, require_instance, require_int, require_nonnegative,
                         require_seed, require_text, require_workers)

__all__ = ["MEMORY_LIMIT", "MAX_SECONDS", "BASE_BYTES", "Experiment", "ArrayExperiment", "Chunk", "Cancelled", "Estimate", "default_workers",
           "chunk_sizes", "chunk_generators", "estimate", "run"]

MEMORY_LIMIT = 500e6  #: bytes, the estimated peak memory (resident) a run may need
MAX_SECONDS = 3600.0  #: s, the longest estimated one-thread run accepted
#: bytes, the resident memory of the interpreter with numpy, scipy, filterpy and this package loaded,
#: which every problem's ``fixed_bytes`` counts first (about 105 MB measured, VmRSS after importing any
#: problem's Monte Carlo, rounded up).  One value for every problem: each problem's memory tests prove
#: that its estimate, this term included, bounds the peak of a child process at the largest run accepted
BASE_BYTES = 130e6


@runtime_checkable
class Experiment(Protocol):
    """What a problem supplies to :func:`run` (all sizes in bytes, times in seconds).

    chunk_size() -> int >= 1
        Realizations drawn together; a function of the settings only.
    fixed_bytes(n_runs) -> float
        What the whole run keeps: the interpreter with its imports, the problem's
        data-independent arrays, the running total (sums, or per-run arrays of all ``n_runs``).
    chunk_bytes(size) -> float
        One chunk of ``size`` realizations in flight: its draws, its filtering, its partial result.
    final_bytes(n_runs) -> float
        What :meth:`result` needs on top of ``fixed_bytes`` (the statistics at the end).
    seconds(n_runs) -> float
        The estimated time on one thread.
    run_chunk(size, rng, chunk) -> partial
        Draw ``size`` realizations from ``rng`` and filter them; call ``chunk.check()`` between
        expensive steps (the one way to cancel: it raises :class:`Cancelled`, which the core
        catches) and ``chunk.tick(n)`` as realizations finish (optional: a chunk that never ticks
        moves the bar when it ends; ``tick`` checks too).  Return the whole chunk's partial result,
        never a part of it.  Runs on a worker thread: read the experiment, never write it.
    empty(n_runs) -> total
        The running total before any chunk, for ``n_runs`` realizations (per-run arrays are
        allocated here, so an experiment need not be told ``n_runs`` when it is built).
    add(total, partial) -> total
        ``partial`` added to ``total``; called in chunk order, in the calling thread.
    result(total, n_runs, seconds) -> result
        The problem's result (its ``checks()`` computed, if they are part of the timed work).

    Optional, asked by :func:`estimate` for its refusals when the caller does not pass them:
    ``what() -> str`` (one realization, e.g. "1001 steps of the EKF") and ``scenario_advice() -> str``
    (how to make one realization smaller).  Optional ``prepare()``: called once by :func:`run` after
    the estimate accepted the run and before ``empty``, to compute what every chunk reads (e.g. the
    filter's data-independent covariances and gains); building the experiment stays cheap, so that the
    estimate comes before anything of the scenario's size exists.

    The lifecycle, in :func:`run`: the estimate (``chunk_size``, the byte counts, ``seconds``), then
    ``prepare()``, ``empty(n_runs)``, ``run_chunk`` on worker threads, ``add`` in chunk order, ``result``.
    """

    def chunk_size(self) -> int: ...

    def fixed_bytes(self, n_runs: int) -> float: ...

    def chunk_bytes(self, size: int) -> float: ...

    def final_bytes(self, n_runs: int) -> float: ...

    def seconds(self, n_runs: int) -> float: ...

    def run_chunk(self, size: int, rng: np.random.Generator, chunk: "Chunk") -> Any: ...

    def empty(self, n_runs: int) -> Any: ...

    def add(self, total: Any, partial: Any) -> Any: ...

    def result(self, total: Any, n_runs: int, seconds: float) -> Any: ...


class ArrayExperiment:
    """Defaults for an :class:`Experiment` whose running total is numpy arrays declared by shape.

    A subclass declares

    ``keep``
        ``"sums"``: the total holds, for every declared array, its sum over the runs (``run_chunk``
        returns the chunk's sums); ``"runs"``: the total holds every run's arrays, ``(n_runs, *shape)``,
        filled in chunk order (``run_chunk`` returns the chunk's ``(size, *shape)`` arrays).
    ``arrays() -> {name: shape}`` or ``{name: (shape, dtype)}``
        The arrays (dtype float64 unless given; with ``"runs"``, the shape of one run's).
    ``CHUNK_SIZE``, ``CHUNK_BYTES_PER_RUN``, ``SECONDS_PER_RUN``
        Realizations per chunk; bytes one realization of a chunk in flight needs (draws, filtering,
        temporaries, measured and rounded up); one-thread seconds per realization.  Or override
        :meth:`chunk_size`, :meth:`chunk_bytes` and :meth:`seconds`.

    and writes ``run_chunk(size, rng, chunk)`` (returning a dict, or a tuple in the order of
    ``arrays()``) and ``result(total, n_runs, seconds)``, ``total`` a dict name -> array.  It gets
    ``empty(n_runs)`` and ``add`` (sums added, or runs written, in chunk order), ``fixed_bytes`` (the
    interpreter, :data:`BASE_BYTES`, plus the declared arrays: times ``n_runs`` with ``"runs"``) and
    ``final_bytes`` (0: override when the result's statistics need memory).
    """

    keep = "sums"

    def arrays(self) -> dict:
        raise NotImplementedError("an ArrayExperiment declares arrays(): {name: shape or (shape, dtype)}")

    def _declared(self) -> dict:
        out = {}
        for name, spec in self.arrays().items():
            shape, dtype = spec if len(spec) == 2 and isinstance(spec[0], tuple) else (spec, float)
            out[name] = (tuple(shape), np.dtype(dtype))
        return out

    def _array_bytes(self) -> int:
        return sum(int(np.prod(shape, dtype=np.int64)) * dtype.itemsize for shape, dtype in self._declared().values())

    def chunk_size(self) -> int:
        return self.CHUNK_SIZE

    def fixed_bytes(self, n_runs: int) -> float:
        return BASE_BYTES + self._array_bytes() * (n_runs if self.keep == "runs" else 1)

    def chunk_bytes(self, size: int) -> float:
        return self.CHUNK_BYTES_PER_RUN * size + (self._array_bytes() if self.keep == "sums" else 0)

    def final_bytes(self, n_runs: int) -> float:
        return 0.0

    def seconds(self, n_runs: int) -> float:
        return self.SECONDS_PER_RUN * n_runs

    def empty(self, n_runs: int) -> dict:
        if self.keep not in ("sums", "runs"):
            raise ValueError(f"keep must be 'sums' or 'runs', got {self.keep!r}")
        if self.keep == "sums":
            return _Total((name, np.zeros(shape, dtype)) for name, (shape, dtype) in self._declared().items())
        return _Total((name, np.empty((n_runs, *shape), dtype)) for name, (shape, dtype) in self._declared().items())

    def add(self, total: dict, partial) -> dict:
        parts = partial.items() if isinstance(partial, dict) else zip(total, partial)
        if self.keep == "sums":
            for name, part in parts:
                total[name] += part
            return total
        start = total.filled
        for name, part in parts:
            stop = start + part.shape[0]
            total[name][start:stop] = part
        total.filled = stop
        return total


class _Total(dict):
    """The total of an :class:`ArrayExperiment`: name -> array, and ``filled``, the runs written."""

    filled = 0


class Cancelled(Exception):
    """Raised inside a chunk by :meth:`Chunk.check` once the run is cancelled (the core catches it)."""


class Chunk:
    """What a running chunk sees of the core: ``check()`` (raise :class:`Cancelled` when the run is
    cancelled: call it between expensive steps, the one way to stop), ``tick(n)`` (n realizations
    done; checks too) and ``cancelled`` (whether the run is cancelled, for display only)."""

    def __init__(self, cancel: threading.Event, lock: threading.Lock, counter: list, on_tick=None):
        self._cancel, self._lock, self._counter, self._on_tick = cancel, lock, counter, on_tick
        self.ticked = 0

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def check(self) -> None:
        if self._cancel.is_set():
            raise Cancelled

    def tick(self, n: int = 1) -> None:
        self.ticked += n
        with self._lock:
            self._counter[0] += n
        if self._on_tick is not None:  # a chunk in the calling thread moves the bar at once
            self._on_tick()
        self.check()


def default_workers() -> int:
    """Threads a Monte Carlo uses by default: the environment variable ``KFCAL_WORKERS`` (an
    integer >= 1) if set, else ``min(2, os.cpu_count())``."""
    env = os.environ.get("KFCAL_WORKERS", "").strip()
    if env:
        try:
            value = int(env)
        except ValueError:
            value = None
        if value is None or value < 1:
            raise ValueError(f"KFCAL_WORKERS must be an integer >= 1, got {env!r}")
        return value
    return max(1, min(2, os.cpu_count() or 1))


#: the most chunks a run is split into (a run the estimate accepts has far fewer)
MAX_CHUNKS = 10**6


def chunk_sizes(chunk: int, n_runs: int) -> list[int]:
    """The sizes of the chunks of ``n_runs`` realizations in chunks of ``chunk``, in order."""
    chunk = require_int("chunk", chunk, minimum=1, maximum=MAX_COUNT)
    n_runs = require_int("n_runs", n_runs, minimum=1, maximum=MAX_COUNT)
    if n_runs // chunk > MAX_CHUNKS:
        raise ValueError(f"n_runs: {n_runs:.3g} realizations in chunks of {chunk} are more than {MAX_CHUNKS:.0e} chunks")
    return [chunk] * (n_runs // chunk) + ([n_runs % chunk] if n_runs % chunk else [])


def chunk_generators(chunk: int, n_runs: int, seed) -> list[tuple[int, np.random.Generator]]:
    """``(size, generator)`` of every chunk, in order: the seed policy of the module docstring
    (``seed``: an int in [0, 2**63 - 1], None for fresh entropy, or a numpy Generator, whose
    ``spawn`` is used)."""
    sizes = chunk_sizes(chunk, n_runs)
    return _generators(sizes, seed if isinstance(seed, np.random.Generator) else require_seed("seed", seed))


def _generators(sizes: list[int], seed) -> list[tuple[int, np.random.Generator]]:
    """:func:`chunk_generators` of the chunk ``sizes``, ``seed`` already checked."""
    if isinstance(seed, np.random.Generator):
        gens = seed.spawn(len(sizes))
    else:
        gens = [np.random.Generator(np.random.PCG64DXSM(s)) for s in np.random.SeedSequence(seed).spawn(len(sizes))]
    return list(zip(sizes, gens))


@dataclass(frozen=True)
class Estimate:
    """The estimate of a run: ``peak_bytes``, ``seconds`` (one thread), ``chunk`` (realizations per
    chunk), ``n_chunks``, ``in_flight`` (chunks run at once) and ``fits`` (within both limits)."""

    peak_bytes: float
    seconds: float
    chunk: int
    n_chunks: int
    in_flight: int

    @property
    def fits(self) -> bool:
        return self.peak_bytes <= MEMORY_LIMIT and self.seconds <= MAX_SECONDS


_TEXTS = dict(runs_name=require_text, params_name=require_text, what=optional(require_text),
              scenario_advice=optional(require_text))


def _message(experiment, name: str, given: str | None, default: str) -> str:
    """``given``, else what the experiment's optional ``name()`` says, else ``default``."""
    if given is not None:
        return given
    ask = getattr(experiment, name, None)
    return str(ask()) if callable(ask) else default


@checked(experiment=partial(require_instance, cls=Experiment), workers=optional(require_workers), extra_bytes=require_nonnegative, **_TEXTS)
def estimate(experiment: Experiment, n_runs: int, workers: int | None = None, *, extra_bytes: float = 0.0,
             runs_name: str = "n_runs", params_name: str = "params", what: str | None = None,
             scenario_advice: str | None = None) -> Estimate:
    """The memory and time of ``run(experiment, n_runs, workers=workers)``, before it starts.

    ``extra_bytes``: what the caller needs after the run while its result is alive (the command
    line's figures, its JSON).  ValueError naming ``params_name`` when even one realization at a time
    does not fit in :data:`MEMORY_LIMIT` (the message: ``"{params_name}: {what} needs about ... MB, more
    than the 500 MB allowed; {scenario_advice}"``, ``what`` describing one realization), naming
    ``runs_name`` when ``n_runs`` realizations need too much memory or more than :data:`MAX_SECONDS`.
    ``what`` and ``scenario_advice`` default to the experiment's ``what()`` and ``scenario_advice()``
    if it has them, else "one realization" and "use a smaller scenario".
    """
    n_runs = require_int(runs_name, n_runs, minimum=1, maximum=MAX_COUNT)
    workers = default_workers() if workers is None else require_int("workers", workers, minimum=1)
    what = _message(experiment, "what", what, "one realization")
    scenario_advice = _message(experiment, "scenario_advice", scenario_advice, "use a smaller scenario")
    chunk = require_int("chunk_size", experiment.chunk_size(), minimum=1)
    n_chunks = -(-n_runs // chunk)  # without listing them: n_runs may be far too large to run
    size = min(chunk, n_runs)
    per_chunk = float(experiment.chunk_bytes(size))
    fixed = float(experiment.fixed_bytes(n_runs))
    final = float(experiment.final_bytes(n_runs)) + float(extra_bytes)
    # Chunks on worker threads: what a worker frees stays with its thread's allocator pool (glibc keeps
    # an arena per thread), so the last phase, in the calling thread, comes on top of the chunks.  One
    # chunk at a time runs in the calling thread, whose freed memory the last phase reuses.
    fit = int((MEMORY_LIMIT - fixed - final) // per_chunk) if per_chunk > 0 else workers
    in_flight = max(1, min(workers, n_chunks, fit))
    peak = fixed + (in_flight * per_chunk + final if in_flight > 1 else max(per_chunk, final))
    seconds = float(experiment.seconds(n_runs))
    if peak > MEMORY_LIMIT:
        one = float(experiment.fixed_bytes(1)) + max(float(experiment.chunk_bytes(1)),
                                                     float(experiment.final_bytes(1)) + float(extra_bytes))
        if one > MEMORY_LIMIT:
            raise ValueError(f"{params_name}: {what} needs about {one / 1e6:.0f} MB, more than the "
                             f"{MEMORY_LIMIT / 1e6:.0f} MB allowed; {scenario_advice}")
        raise ValueError(f"{runs_name}: {n_runs} realizations ({what}) need about {peak / 1e6:.0f} MB, more than "
                         f"the {MEMORY_LIMIT / 1e6:.0f} MB allowed; use fewer realizations")
    if seconds > MAX_SECONDS:
        raise ValueError(f"{runs_name}: {n_runs} realizations would take about {seconds / 3600:.3g} h, more "
                         f"than the {MAX_SECONDS / 3600:g} h allowed; use fewer")
    return Estimate(peak, seconds, chunk, n_chunks, in_flight)


@checked(experiment=partial(require_instance, cls=Experiment), workers=optional(require_workers), progress=optional(require_bool), desc=require_text,
         extra_bytes=require_nonnegative, **_TEXTS)
def run(experiment: Experiment, n_runs: int, seed=0, *, workers: int | None = None, progress: bool | None = False,
        desc: str = "Monte Carlo", extra_bytes: float = 0.0, runs_name: str = "n_runs",
        params_name: str = "params", what: str | None = None, scenario_advice: str | None = None):
    """Run ``n_runs`` realizations of ``experiment`` in seeded chunks on threads; return
    ``experiment.result(total, n_runs, seconds)``.

    seed : int in [0, 2**63 - 1], None (fresh entropy) or a numpy Generator (:func:`chunk_generators`)
    workers : threads (default :func:`default_workers`); the result does not depend on it
    progress : show a bar over realizations (None: unless CI or KFCAL_QUIET is set)
    extra_bytes, runs_name, params_name, what, scenario_advice : passed to :func:`estimate`, which runs first

    Each argument is checked once: ``seed`` here, ``n_runs``, ``workers`` and the experiment's chunk size
    by :func:`estimate`; the problem checks its own settings when it builds the experiment.
    """
    if not isinstance(seed, np.random.Generator):
        seed = require_seed("seed", seed)
    plan = estimate(experiment, n_runs, workers, extra_bytes=extra_bytes, runs_name=runs_name,
                    params_name=params_name, what=what, scenario_advice=scenario_advice)
    n_runs = int(n_runs)
    start = time.perf_counter()
    chunks = _generators(chunk_sizes(plan.chunk, n_runs), seed)
    cancel, lock, counter = threading.Event(), threading.Lock(), [0, 0]  # ticks by workers, ticks shown
    bar = progress_bar(n_runs, desc, progress)
    prepare = getattr(experiment, "prepare", None)
    if callable(prepare):
        prepare()
    total = experiment.empty(n_runs)

    def show():
        with lock:
            new, counter[1] = counter[0] - counter[1], counter[0]
        if new:
            bar.update(new)

    def one(size, rng, here=False):
        chunk = Chunk(cancel, lock, counter, show if here else None)
        try:
            part = experiment.run_chunk(size, rng, chunk)
        except Cancelled:  # the run is being torn down: nothing is added after a cancellation
            return None
        rest = size - chunk.ticked  # a chunk that did not tick moves the bar when it ends
        if rest:
            with lock:
                counter[0] += rest
        return part

    try:
        if plan.in_flight == 1:
            for size, rng in chunks:
                total = experiment.add(total, one(size, rng, here=True))
                show()
        else:
            pool = ThreadPoolExecutor(max_workers=plan.in_flight, thread_name_prefix="kfcal-mc")
            try:
                pending = deque()
                queue = iter(chunks)
                for size, rng in itertools.islice(queue, plan.in_flight):
                    pending.append(pool.submit(one, size, rng))
                while pending:
                    future = pending.popleft()
                    while True:
                        try:
                            part = future.result(timeout=0.1)
                            break
                        except FutureTimeout:
                            show()
                    total = experiment.add(total, part)
                    show()
                    for size, rng in itertools.islice(queue, 1):
                        pending.append(pool.submit(one, size, rng))
            finally:
                cancel.set()  # after an interruption, running chunks stop at their next tick
                pool.shutdown(wait=False, cancel_futures=True)
    finally:
        cancel.set()
        bar.close()
    return experiment.result(total, n_runs, time.perf_counter() - start)
