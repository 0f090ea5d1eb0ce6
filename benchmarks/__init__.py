"""Speed figures for `make bench`: each ``bench_*.py`` module here has ``run() -> dict``.

``ehw bench`` (= ``python -m benchmarks``) runs them all (or those named on the command line),
writes this run's figures to a fresh ``results/bench/<date>-<time>/bench.json`` (``latest``
points at it) and merges them into ``results/bench.json``, keeping the keys of modules not run
this time.
"""

import time


def best_time(fn, repeats: int) -> float:
    """The shortest of ``repeats`` wall-clock timings of ``fn()`` (the least disturbed by a shared machine)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best
