"""Reference AND-OR array: truth tables per second, against a pure-Python evaluation."""

from __future__ import annotations

import time

import numpy as np

from ga.truth_table import truth_tables, truth_tables_python


def _best_time(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run() -> dict:
    rng = np.random.default_rng(2026)
    # Genomes of realistic density: each literal connected with probability 1/3 each polarity.
    from ga.genome import N_ROWS

    pop = rng.integers(0, 1 << 19, size=(500, N_ROWS), dtype=np.uint32)
    truth_tables(pop)  # warm the tables
    fast = _best_time(lambda: truth_tables(pop), 30) / len(pop)
    few = pop[:4]
    slow = _best_time(lambda: truth_tables_python(few), 2) / len(few)
    assert np.array_equal(np.array(truth_tables_python(few), dtype=np.uint8), truth_tables(few))
    return {
        "truth_tables_per_s": round(1.0 / fast),
        "truth_tables_python_per_s": round(1.0 / slow, 1),
        "truth_tables_speedup_vs_python": round(slow / fast, 1),
        "truth_tables_500_ms": round(fast * 500 * 1e3, 3),
    }
