"""The on-line lifetime tables of docs/online.md: configurations x seeds -> one Markdown table.

    python experiments/online_table.py round5                       # the table of round 5
    python experiments/online_table.py heldout                      # its held-out seeds 21-40
    python experiments/online_table.py round5 --seeds 1-5 --jobs 2  # part of it
    python experiments/online_table.py round5 --seeds 1 --budget 500   # a smoke run (seconds)
    python experiments/online_table.py --list                       # the tables and their rows

Each run is ``cosim.online.run.make_run(OnlineConfig(seed=S, max_interactions=BUDGET, **row)).run()``
on the reference boards; a cell is the interactions to 64 targets, or "t @ B" when the budget B
ran out first (counted as B in the medians, so those are lower bounds). Besides the table the
script writes one JSON line per run (``--out``, default build/experiments/<table>.jsonl: the
figures, the phase reasons and how often each failure detector stopped a leg) and reuses the
lines already there, so an interrupted table goes on where it stopped.

Every row spells out distance_rule and loop_cycles, and runs with the rules before issue 17's
round 8 (``loop_blame`` "leg", no failure rates: ``BEFORE_ROUND8``), so a table means what it
meant when it was measured. The tables of rounds 1, 2 and 4 and the rows of options measured and
dropped are in this script at the tag ``research/round-18`` (docs/research-log.md).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

# The rules of rounds 1-7 (issue 12's defaults): every row runs with them unless it says otherwise.
BEFORE_ROUND8 = {"loop_blame": "leg", "fail_rates": False}
# The first reading (the defaults before issue 12): the SPEC fitness as first written.
FIRST = {"distance_rule": "covered", "loop_cycles": 0}
ROUND3 = {**FIRST, "loop_window": 100, "loop_repeats": 4, "loop_reentries": 4, "loop_radius_mm": 80.0}
W100 = {**FIRST, "loop_window": 100, "loop_repeats": 0, "loop_reentries": 0, "loop_radius_mm": 0.0}
ISSUE12 = {**ROUND3, "distance_rule": "forward", "loop_cycles": 1}

# name -> (what it is, seeds, budget, rows: (label, options)); options are OnlineConfig fields.
TABLES = {
    "round3": ("round 3: the odometry check and the round-3 default", "1-10", 100_000, [
        ("default before round 3 (W = 100)", W100),
        ("lr4 r6", {**W100, "loop_repeats": 4, "loop_reentries": 6}),
        ("lr4 r6 rad100", {**W100, "loop_repeats": 4, "loop_reentries": 6, "loop_radius_mm": 100.0}),
        ("lr4 r6 rad60", {**W100, "loop_repeats": 4, "loop_reentries": 6, "loop_radius_mm": 60.0}),
        ("lr3 r4 rad80", {**ROUND3, "loop_repeats": 3}),
        ("lr4 r3 rad80", {**ROUND3, "loop_reentries": 3}),
        ("lr4 r4 rad120", {**ROUND3, "loop_radius_mm": 120.0}),
        ("lr4 r4 rad80 (the round-3 default)", ROUND3),
    ]),
    "round5": ("round 5: the forward distance and the one-round cycle detector", "1-20", 40_000, [
        ("SPEC fitness (first reading), round-3 defaults", ROUND3),
        ("first reading + --loop-cycles 1", {**ROUND3, "loop_cycles": 1}),
        ("--distance forward", {**ROUND3, "distance_rule": "forward"}),
        ("--distance forward --loop-cycles 1 (the default now)", ISSUE12),
    ]),
    "heldout": ("held-out seeds of round 5 (measured after the choice)", "21-40", 40_000, [
        ("SPEC fitness (first reading), round-3 defaults", ROUND3),
        ("--distance forward --loop-cycles 1 (the default now)", ISSUE12),
    ]),
    "one_obstacle": ("round 5 in the one-obstacle arena", "1-5", 40_000, [
        ("SPEC fitness (first reading), round-3 defaults", {**ROUND3, "arena": "one_obstacle"}),
        ("--distance forward --loop-cycles 1", {**ISSUE12, "arena": "one_obstacle"}),
    ]),
}


def seed_range(text: str) -> list[int]:
    """"1-5" -> [1, 2, 3, 4, 5]; "1,4,7" -> [1, 4, 7]."""
    seeds = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += list(range(int(lo), int(hi or lo) + 1))
    return seeds


def lifetime(task: tuple[str, dict, int, int]) -> dict:
    """One run of a row: the figures and how its legs were stopped."""
    from cosim.online.config import OnlineConfig
    from cosim.online.run import make_run

    label, options, seed, budget = task
    run = make_run(OnlineConfig(seed=seed, max_interactions=budget, **{**BEFORE_ROUND8, **options})).run()
    s = run.summary()
    detectors = Counter(p.get("detector", p["reason"]) for p in s["phases"])
    return {"row": label, "seed": seed, "budget": budget, "options": options,
            "targets": s["targets_reached"], "interactions": s["interactions"],
            "generations": s["generations"], "world_states": s["world_states"],
            "transitions": s["transitions"], "phase_reasons": s["phase_reasons"],
            "stops": dict(sorted(detectors.items())), "wall_time_s": s["wall_time_s"]}


def cell(r: dict, n_targets: int = 64) -> str:
    if r["targets"] >= n_targets:
        return f"{r['interactions']:,}"
    return f"**{r['targets']} @ {r['budget'] // 1000}k**" if r["budget"] % 1000 == 0 else \
        f"**{r['targets']} @ {r['budget']:,}**"


def table(name: str, results: list[dict], seeds: list[int], command: str) -> str:
    title, *_ = TABLES[name]
    lines = [f"{title}. Command: `{command}`", "",
             "| configuration | " + " | ".join(f"seed {s}" for s in seeds) + " | median | worst | stops (all seeds) |",
             "|---|" + "---|" * (len(seeds) + 3)]
    for label, _options in TABLES[name][3]:
        runs = {r["seed"]: r for r in results if r["row"] == label}
        cells = [cell(runs[s]) if s in runs else "" for s in seeds]
        done = [runs[s] for s in seeds if s in runs]
        costs = [r["interactions"] if r["targets"] >= 64 else r["budget"] for r in done]
        stops = sum((Counter(r["stops"]) for r in done), Counter())
        median = f"{statistics.median(costs):,.0f} ({sum(r['targets'] >= 64 for r in done)}/{len(done)})" if done else ""
        worst = f"{max(costs):,}" if done else ""
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {median} | {worst} | "
                     + ", ".join(f"{k} {v}" for k, v in stops.items()) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("table", nargs="?", choices=sorted(TABLES))
    p.add_argument("--seeds", help="seeds, e.g. 1-5 or 1,3 (default: the table's)")
    p.add_argument("--budget", type=int, help="max_interactions of a run (default: the table's)")
    p.add_argument("--rows", help="only the rows whose label contains this text")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--out", type=Path, help="the JSON lines (default build/experiments/<table>.jsonl)")
    p.add_argument("--list", action="store_true", help="list the tables and their rows")
    args = p.parse_args(argv)
    if args.list or args.table is None:
        for name, (title, seeds, budget, rows) in TABLES.items():
            print(f"{name}: {title} (seeds {seeds}, budget {budget:,})")
            for label, options in rows:
                print(f"    {label}: {options}")
        return 0
    title, default_seeds, default_budget, rows = TABLES[args.table]
    seeds = seed_range(args.seeds or default_seeds)
    budget = args.budget or default_budget
    chosen = [(label, options) for label, options in rows if not args.rows or args.rows in label]
    out = args.out or Path("build/experiments") / f"{args.table}.jsonl"
    out.parent.mkdir(parents=True, exist_ok=True)
    done = [json.loads(line) for line in out.read_text().splitlines()] if out.exists() else []
    have = {(r["row"], r["seed"], r["budget"]) for r in done}
    tasks = [(label, options, s, budget) for label, options in chosen for s in seeds
             if (label, s, budget) not in have]
    print(f"{args.table}: {len(tasks)} lifetimes to run, {len(have)} in {out}", file=sys.stderr)
    pool = ProcessPoolExecutor(max_workers=args.jobs) if args.jobs > 1 else None
    with out.open("a") as f:
        for r in (pool.map(lifetime, tasks) if pool else map(lifetime, tasks)):
            f.write(json.dumps(r) + "\n")
            f.flush()
            done.append(r)
            print(f"  {r['row']}, seed {r['seed']}: {cell(r)}", file=sys.stderr)
    if pool is not None:
        pool.shutdown()
    results = [r for r in done if r["budget"] == budget]
    command = " ".join(["python experiments/online_table.py", *(sys.argv[1:] if argv is None else argv)])
    text = table(args.table, results, seeds, command)
    (out.with_suffix(".md")).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
