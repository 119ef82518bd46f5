"""The shared Monte Carlo core (kfcal_helpers.montecarlo) on a toy experiment: seeds, chunk order,
workers, estimates, cancellation."""

import signal
import threading

import numpy as np
import pytest

from kfcal_helpers import montecarlo as core


class Toy:
    """Realizations are 3-vectors of normals; the total is the sum and the sum of squares, plus the
    list of chunk sizes seen (to check the chunk order)."""

    def __init__(self, chunk=7, bytes_per_run=1e3, fixed=1e6, ticks=False, stop_after=None):
        self.chunk, self.bytes_per_run, self.fixed, self.ticks = chunk, bytes_per_run, fixed, ticks
        self.stop_after = stop_after
        self.started = threading.Event()

    def chunk_size(self):
        return self.chunk

    def fixed_bytes(self, n_runs):
        return self.fixed

    def chunk_bytes(self, size):
        return self.bytes_per_run * size

    def final_bytes(self, n_runs):
        return 0.0

    def seconds(self, n_runs):
        return 1e-6 * n_runs

    def run_chunk(self, size, rng, chunk):
        self.started.set()
        x = rng.standard_normal((size, 3))
        if self.ticks:
            for _ in range(size):
                chunk.tick()
        if self.stop_after is not None:
            while True:  # a long chunk that only an interruption stops, at its next check()
                chunk.check()
                threading.Event().wait(0.01)
        return size, x.sum(0), (x ** 2).sum(0)

    def empty(self, n_runs):
        self.emptied_for = n_runs
        return [0, np.zeros(3), np.zeros(3), []]

    def add(self, total, part):
        total[0] += part[0]
        total[1] += part[1]
        total[2] += part[2]
        total[3].append(part[0])
        return total

    def result(self, total, n_runs, seconds):
        assert total[0] == n_runs
        return total


@pytest.mark.parametrize("ticks", [False, True])
def test_bit_identical_for_any_workers(ticks):
    runs = [core.run(Toy(ticks=ticks), 100, 5, workers=w) for w in (1, 2, 3)]
    for r in runs[1:]:
        assert r[3] == runs[0][3] == [7] * 14 + [2]
        assert np.array_equal(r[1], runs[0][1]) and np.array_equal(r[2], runs[0][2])


def test_seed_policy_is_seedsequence_spawn_pcg64dxsm():
    got = core.chunk_generators(7, 15, 42)
    children = np.random.SeedSequence(42).spawn(3)
    assert [s for s, _ in got] == [7, 7, 1]
    for (_, g), child in zip(got, children):
        assert isinstance(g.bit_generator, np.random.PCG64DXSM)
        assert g.standard_normal() == np.random.Generator(np.random.PCG64DXSM(child)).standard_normal()
    # a Generator seed spawns its own children
    a = core.chunk_generators(7, 15, np.random.default_rng(3))
    b = np.random.default_rng(3).spawn(3)
    assert a[2][1].random() == b[2].random()


def test_same_draws_as_redrawing_the_chunks():
    total = core.run(Toy(), 20, 11, workers=2)
    redraw = sum(g.standard_normal((s, 3)).sum(0) for s, g in core.chunk_generators(7, 20, 11))
    assert np.array_equal(total[1], redraw)


def test_estimate_counts_chunks_in_flight_and_refuses():
    toy = Toy(chunk=10, bytes_per_run=1e6, fixed=100e6)
    est = core.estimate(toy, 100, workers=2)
    assert est.in_flight == 2 and est.n_chunks == 10 and est.peak_bytes == 100e6 + 2 * 10e6 and est.fits
    # only three chunks of 10 runs at 100 MB each fit beside the fixed 100 MB
    big = Toy(chunk=10, bytes_per_run=10e6, fixed=100e6)
    assert core.estimate(big, 100, workers=8).in_flight == 4
    with pytest.raises(ValueError, match="^n_runs: .*more than the 500 MB"):
        core.estimate(Toy(chunk=100, bytes_per_run=10e6, fixed=100e6), 100, runs_name="n_runs")
    with pytest.raises(ValueError, match="^params: .*smaller scenario"):
        core.estimate(Toy(chunk=1, bytes_per_run=1e9), 5)
    slow = Toy()
    slow.seconds = lambda n: 1e4
    with pytest.raises(ValueError, match="^runs: .*h allowed"):
        core.estimate(slow, 5, runs_name="runs")


def test_the_core_prepares_then_gives_empty_the_runs_and_asks_the_experiment_for_its_messages():
    toy, calls = Toy(), []
    toy.prepare = lambda: calls.append(hasattr(toy, "emptied_for"))
    core.estimate(toy, 20)
    assert calls == []  # the estimate prepares nothing
    core.run(toy, 20, 1)
    assert toy.emptied_for == 20 and calls == [False]  # prepared once, before empty
    big = Toy(chunk=1, bytes_per_run=1e9)
    big.what = lambda: "a 3-vector"
    big.scenario_advice = lambda: "use fewer states"
    with pytest.raises(ValueError, match=r"^params: a 3-vector needs about \d+ MB, .*; use fewer states$"):
        core.estimate(big, 5)
    with pytest.raises(ValueError, match=r"^params: one draw needs .*; use fewer states$"):  # the caller's wins
        core.run(big, 5, what="one draw")


class Sums(core.ArrayExperiment):
    """Declared arrays summed over the runs (``keep = "sums"``)."""

    keep, CHUNK_SIZE, CHUNK_BYTES_PER_RUN, SECONDS_PER_RUN = "sums", 7, 100.0, 1e-6

    def arrays(self):
        return {"x": (3,), "n": ((), int)}

    def run_chunk(self, size, rng, chunk):
        return {"x": rng.standard_normal((size, 3)).sum(0), "n": size}

    def result(self, total, n_runs, seconds):
        return total


class Runs(Sums):
    """Declared arrays of every run (``keep = "runs"``), returned as a tuple in the declared order."""

    keep = "runs"

    def arrays(self):
        return {"x": (3,), "k": ((), int)}

    def run_chunk(self, size, rng, chunk):
        return rng.standard_normal((size, 3)), np.full(size, size)


def test_array_experiment_sums_or_keeps_its_declared_arrays_and_counts_their_bytes():
    chunks = core.chunk_generators(7, 20, 5)
    draws = [g.standard_normal((s, 3)) for s, g in chunks]
    for workers in (1, 2):
        s = core.run(Sums(), 20, 5, workers=workers)
        expected = np.zeros(3)
        for d in draws:
            expected += d.sum(0)
        assert s["n"] == 20 and s["n"].dtype == int and np.array_equal(s["x"], expected)
        r = core.run(Runs(), 20, 5, workers=workers)
        assert np.array_equal(r["x"], np.concatenate(draws)) and list(r["k"]) == [7] * 14 + [6] * 6
    assert isinstance(Sums(), core.Experiment) and Sums().chunk_size() == 7
    assert Sums().fixed_bytes(10) == core.BASE_BYTES + 32 and Sums().chunk_bytes(7) == 700 + 32
    assert Runs().fixed_bytes(10) == core.BASE_BYTES + 10 * 32 and Runs().chunk_bytes(7) == 700
    assert Sums().final_bytes(10) == 0 and Sums().seconds(10) == pytest.approx(1e-5)


def test_default_workers_reads_kfcal_workers(monkeypatch):
    monkeypatch.setenv("KFCAL_WORKERS", "3")
    assert core.default_workers() == 3
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv("KFCAL_WORKERS", bad)
        with pytest.raises(ValueError, match="KFCAL_WORKERS must be an integer >= 1"):
            core.default_workers()
    monkeypatch.delenv("KFCAL_WORKERS")
    assert 1 <= core.default_workers() <= 2


def test_interruption_cancels_the_running_chunks():
    """Ctrl-C (SIGINT, a KeyboardInterrupt in the calling thread) while chunks run on threads stops them."""
    toy = Toy(chunk=1, stop_after=True)

    def interrupt():
        toy.started.wait(5)
        threading.Event().wait(0.2)
        signal.raise_signal(signal.SIGINT)

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    thread = threading.Thread(target=interrupt)
    thread.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            core.run(toy, 4, 0, workers=2)
    finally:
        thread.join(5)
        signal.signal(signal.SIGINT, previous)
    workers = [t for t in threading.enumerate() if t.name.startswith("kfcal-mc")]
    for t in workers:
        t.join(5)
    assert not any(t.is_alive() for t in workers)
