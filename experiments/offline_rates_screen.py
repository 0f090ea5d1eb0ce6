"""Screen operator rates of the paper's off-line method (issue 38, round 8): one variant, seeds, a table.

    python experiments/offline_rates_screen.py VARIANT --seeds 511-520 [--cap 1500] [--jobs 2]
"""
import argparse
import json
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

BASE = {"literal_rate": 0.004, "output_rate": 0.004, "switch_rate": 0.01, "replace_rate": 0.005}


def scaled(f, **extra):
    return {**{k: v * f for k, v in BASE.items()}, **extra}


VARIANTS = {
    "base": {},
    "half": scaled(0.5),
    "quarter": scaled(0.25),
    "half_x02": scaled(0.5, crossover_rate=0.2),
    "x02": {"crossover_rate": 0.2},
    "double": scaled(2.0),
    "x08": {"crossover_rate": 0.8},
    "d05": {"directed_rate": 0.5},
    "lit7": {"directed_literals": 7},
    "d07": {"directed_rate": 0.7},
    "d05_x08": {"directed_rate": 0.5, "crossover_rate": 0.8},
    "lit6": {"directed_literals": 6},
}


def one(task):
    variant, seed, cap = task
    from cosim.offline.run import default_ga_config, run_offline
    out = Path(f"build/o38r8/{variant}/seed{seed}")
    summ = out / "summary.json"
    if summ.exists():
        return json.loads(summ.read_text())
    return run_offline(seed, generations_cap=cap, out=out, max_leg_steps=150, resume=True,
                       ga_config=default_ga_config(**VARIANTS[variant]), progress=False, plots=False,
                       transfer_trials=0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("variant", choices=sorted(VARIANTS))
    ap.add_argument("--seeds", default="511-520")
    ap.add_argument("--cap", type=int, default=1500)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    seeds = list(range(lo, hi + 1))
    rows = []
    with ProcessPoolExecutor(a.jobs) as ex:
        for s, r in zip(seeds, ex.map(one, [(a.variant, s, a.cap) for s in seeds])):
            rows.append((s, r["targets_reached"], r["generations"], r["interactions"]))
            print(a.variant, s, r["targets_reached"], r["generations"], r["interactions"], flush=True)
    ok = sum(t >= 64 for _, t, _, _ in rows)
    capped = [i if t >= 64 else float("inf") for _, t, _, i in rows]
    print(f"{a.variant}: {ok}/{len(rows)} reach 64; median interactions (capped = inf) "
          f"{statistics.median(capped):,.0f}; median targets {statistics.median(t for _, t, _, _ in rows)}")


if __name__ == "__main__":
    sys.exit(main())
