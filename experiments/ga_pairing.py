"""The host GA and the hardware GA on the same stored world models (issue 14, quality).

Each seed starts both GAs from the same initial population (the on-line run's: the host GA's
first ``ask``) and runs ``phases`` learning phases of 10 generations on one stored model
(benchmarks/data/world_model_*.json, taken from the lifetime of seed 1), the population kept
between phases as in a lifetime. After each phase the best individual's SPEC fitness and counts
are recorded. No robot: this separates the GA itself from the chaos of a lifetime.

    python experiments/ga_pairing.py --seeds 1-30 --phases 5 [--lanes 7] [--distance forward]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_learning import models  # noqa: E402
from cosim.online.learning_phase import hardware_ga_config, hardware_seed  # noqa: E402
from cosim.online.config import OnlineConfig  # noqa: E402
from experiments.online_table import seed_range  # noqa: E402
from ga import hardware_ga as hg  # noqa: E402
from ga.evaluator import EvalResult, evaluate_population, fitness  # noqa: E402
from ga.evolution import GeneticAlgorithm  # noqa: E402


def host_phases(config: OnlineConfig, model, phases: int) -> list[float]:
    ga = GeneticAlgorithm(config.ga_config(), np.random.default_rng(config.seed))
    best = []
    for _ in range(phases):
        for _ in range(config.generations_per_phase):
            counts = evaluate_population(ga.ask(), model, distance_rule=config.distance_rule)
            ga.tell(fitness(counts, model.n_states))
        best.append(float(ga.last_fitness.max()))
    return best


def hardware_phases(config: OnlineConfig, model, phases: int) -> list[float]:
    initial = GeneticAlgorithm(config.ga_config(), np.random.default_rng(config.seed)).ask()
    ga = hg.HardwareGA(hardware_ga_config(config), hardware_seed(config.seed), initial)
    best = []
    for _ in range(phases):
        _, (c, lo, d), _ = ga.learn(model, config.generations_per_phase, config.reflex, config.distance_rule)
        counts = EvalResult(np.array([c]), np.array([lo]), np.array([d]))
        best.append(float(fitness(counts, model.n_states)[0]))
    return best


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="1-30")
    p.add_argument("--phases", type=int, default=5)
    p.add_argument("--lanes", type=int, default=hg.LEARNER_LANES)
    p.add_argument("--out", type=Path, default=Path("build/experiments/ga_pairing.jsonl"))
    args = p.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for name, model in models().items():
        diffs = []
        for seed in seed_range(args.seeds):
            config = OnlineConfig(seed=seed, lanes=args.lanes)
            host = host_phases(config, model, args.phases)
            hw = hardware_phases(config, model, args.phases)
            diffs.append([h - s for h, s in zip(hw, host)])
            with args.out.open("a") as f:
                f.write(json.dumps({"model": name, "seed": seed, "lanes": args.lanes, "host": host, "hardware": hw}) + "\n")
        d = np.array(diffs)
        if len(d) < 2:  # no standard error from one seed
            print(f"model {name}: hardware - host best fitness per phase: " + ", ".join(f"{m:+.4f}" for m in d[0]))
            continue
        print(f"model {name}: hardware - host best fitness per phase, mean (sd of mean): "
              + ", ".join(f"{m:+.4f} ({s:.4f})" for m, s in zip(d.mean(0), d.std(0, ddof=1) / np.sqrt(len(d)))),
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
