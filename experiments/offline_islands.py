"""Issue 38, off-line round 9: two lineages (islands) against the state-1 trap of round 7.

The population of 20 is split into K islands of 20 / K; each island breeds on its own (its own
elite, tournament 5 within it, the same operators), so a lineage trapped on one controller does not
pull the other into its basin. Optionally every M generations the best individual of the best island
replaces the worst of each other island (migration). Same population, same evaluations a generation.

    python experiments/offline_islands.py VARIANT --seeds 511-520 [--cap 1500] [--jobs 1]
"""
import argparse
import json
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

VARIANTS = {
    "base": {"islands": 1, "migrate": 0},
    "islands2": {"islands": 2, "migrate": 0},
    "islands2_m100": {"islands": 2, "migrate": 100},
    "islands4": {"islands": 4, "migrate": 0},
}


def island_ga(islands: int, migrate: int):
    from ga import evolution

    class IslandGA(evolution.GeneticAlgorithm):
        def breed(self, pop, fitness, failures=None):
            cfg = self.config
            size = cfg.population // islands
            parts = []
            for k in range(islands):
                sl = slice(k * size, (k + 1) * size)
                sub = evolution.GeneticAlgorithm.__new__(evolution.GeneticAlgorithm)
                sub.config = evolution.GAConfig(**{**cfg.to_dict(), "population": size,
                                                   "tournament": min(cfg.tournament, size)})
                sub.rng = self.rng
                parts.append(sub.breed(pop[sl], fitness[sl], None if failures is None else failures[sl]))
            nxt = np.concatenate(parts)
            # the generation just bred is self.generation + 1 (tell increments after breed)
            if migrate and islands > 1 and (self.generation + 1) % migrate == 0:
                best = [int(np.argmax(fitness[k * size:(k + 1) * size])) + k * size for k in range(islands)]
                top = max(best, key=lambda i: fitness[i])
                for k in range(islands):
                    if top // size != k:
                        worst = int(np.argmin(fitness[k * size:(k + 1) * size]))
                        if worst != 0:  # never the island's elite (slot 0 of its part)
                            nxt[k * size + worst] = pop[top]
            return nxt.astype(pop.dtype)

    return IslandGA


def one(task):
    variant, seed, cap = task
    import cosim.offline.run as run
    v = VARIANTS[variant]
    if v["islands"] > 1:
        run.GeneticAlgorithm = island_ga(v["islands"], v["migrate"])
    out = Path(f"build/o38i/{variant}/seed{seed}")
    summ = out / "summary.json"
    if summ.exists():
        return json.loads(summ.read_text())
    return run.run_offline(seed, generations_cap=cap, out=out, max_leg_steps=150, progress=False, plots=False,
                           transfer_trials=0, resume=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("variant", choices=sorted(VARIANTS))
    ap.add_argument("--seeds", default="511-520")
    ap.add_argument("--cap", type=int, default=1500)
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    seeds = list(range(lo, hi + 1))
    rows = []
    with ProcessPoolExecutor(a.jobs) as ex:
        for s, r in zip(seeds, ex.map(one, [(a.variant, s, a.cap) for s in seeds])):
            rows.append((s, r["targets_reached"], r["generations"], r["interactions"]))
            print(s, r["targets_reached"], r["generations"], r["interactions"], flush=True)
    ok = sum(t >= 64 for _, t, _, _ in rows)
    capped = [i if t >= 64 else float("inf") for _, t, _, i in rows]
    print(f"{a.variant}: {ok}/{len(rows)} reach 64; median interactions (capped = inf) "
          f"{statistics.median(capped):,.0f}; median targets {statistics.median(t for _, t, _, _ in rows)}")


if __name__ == "__main__":
    sys.exit(main())
