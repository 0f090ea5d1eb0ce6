"""Screen variants of the paper's off-line method (issue 38): one variant, several seeds, a table.

    python experiments/offline_screen.py VARIANT --seeds 501-510 [--cap 1500] [--jobs 2]
"""
import argparse
import json
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

VARIANTS = {
    "base": {},
    "window16": {"directed_window": 16},
    "window32": {"directed_window": 32},
    "window16_d05": {"directed_window": 16, "ga": {"directed_rate": 0.5}},
    "restart150": {"restart_after": 150},
    "restart300": {"restart_after": 300},
    "window16_restart150": {"directed_window": 16, "restart_after": 150},
    "sectors05": {"ga": {"directed_sectors": 0.5}},
    "sectors10": {"ga": {"directed_sectors": 1.0}},
    "half_rates": {"ga": {"literal_rate": 0.002, "output_rate": 0.002, "switch_rate": 0.005, "replace_rate": 0.0025}},
    "window16_half": {"directed_window": 16, "ga": {"literal_rate": 0.002, "output_rate": 0.002,
                                                     "switch_rate": 0.005, "replace_rate": 0.0025}},
}


def one(task):
    variant, seed, cap = task
    from cosim.offline.run import default_ga_config, run_offline
    v = VARIANTS[variant]
    out = Path(f"build/o38/{variant}/seed{seed}")
    summ = out / "summary.json"
    if summ.exists():
        return json.loads(summ.read_text())
    return run_offline(seed, generations_cap=cap, out=out, max_leg_steps=150, ga_config=default_ga_config(**v.get("ga", {})),
                       progress=False, plots=False, transfer_trials=0, directed_window=v.get("directed_window", 0),
                       restart_after=v.get("restart_after", 0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("variant", choices=sorted(VARIANTS))
    ap.add_argument("--seeds", default="501-510")
    ap.add_argument("--cap", type=int, default=1500)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    seeds = list(range(lo, hi + 1))
    with ProcessPoolExecutor(a.jobs) as ex:
        res = list(ex.map(one, [(a.variant, s, a.cap) for s in seeds]))
    rows = []
    for s, r in zip(seeds, res):
        rows.append((s, r["targets_reached"], r["generations"], r["interactions"]))
        print(s, r["targets_reached"], r["generations"], r["interactions"], flush=True)
    ok = sum(t >= 64 for _, t, _, _ in rows)
    capped = [i if t >= 64 else float("inf") for _, t, _, i in rows]
    print(f"{a.variant}: {ok}/{len(rows)} reach 64; median interactions (capped = inf) "
          f"{statistics.median(capped):,.0f}; median targets {statistics.median(t for _, t, _, _ in rows)}")


if __name__ == "__main__":
    sys.exit(main())
