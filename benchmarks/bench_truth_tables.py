"""Reference AND-OR array: truth tables per second, against a pure-Python evaluation."""

from __future__ import annotations


import numpy as np

from ga.genome import N_ROWS, ROW_BITS
from ga.truth_table import truth_tables, truth_tables_python
from benchmarks import best_time



def run() -> dict:
    rng = np.random.default_rng(2026)
    # A population of 500 (the on-line GA's size) of uniform random genomes: every bit set with
    # probability 1/2. The cost does not depend on the bits (table look-ups, no early exit).
    pop = rng.integers(0, 1 << ROW_BITS, size=(500, N_ROWS), dtype=np.uint32)
    truth_tables(pop)  # warm the tables
    fast = best_time(lambda: truth_tables(pop), 50) / len(pop)
    one = best_time(lambda: truth_tables(pop[0]), 200)
    few = pop[:8]
    slow = best_time(lambda: truth_tables_python(few), 3) / len(few)
    for reflex in (False, True):
        assert np.array_equal(np.array(truth_tables_python(few, reflex), dtype=np.uint8), truth_tables(few, reflex))
    return {
        "truth_tables_per_s": round(1.0 / fast),
        "truth_tables_python_per_s": round(1.0 / slow, 1),
        "truth_tables_speedup_vs_python": round(slow / fast, 1),
        "truth_tables_500_ms": round(fast * 500 * 1e3, 3),
        "truth_tables_one_genome_us": round(one * 1e6, 1),
    }
