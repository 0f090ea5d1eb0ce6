"""GA overhead: time per generation spent outside fitness evaluation (population 500)."""

from __future__ import annotations

import time

import numpy as np

from ga.evolution import GAConfig, GeneticAlgorithm


def run() -> dict:
    # The on-line experiment's shape: population 500, tournament 20, elitism.
    ga = GeneticAlgorithm(GAConfig(population=500, tournament=20), np.random.default_rng(2026))
    fitness_rng = np.random.default_rng(7)
    fitness = [fitness_rng.random(500) for _ in range(60)]
    for f in fitness[:10]:  # warm up
        ga.tell(f)
    times = []
    for f in fitness[10:]:
        t0 = time.perf_counter()
        ga.ask()
        ga.tell(f)
        times.append(time.perf_counter() - t0)
    return {
        "ga_generation_overhead_s": round(float(np.median(times)), 6),
        "ga_generation_overhead_p90_s": round(float(np.percentile(times, 90)), 6),
    }
