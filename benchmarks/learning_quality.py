"""Quality of --ga hardware against the host GA: on-line lifetimes over seeds (issue 14).

    .venv/bin/python -m benchmarks.learning_quality --seeds 21-40 [--max-interactions 40000] [--ga hardware]

Runs the default on-line configuration (reference backend) with ``ga="host"`` and
``ga="hardware"`` on each seed, alternately (``--ga``: only one of them, e.g. when the host GA's
lifetimes come from ``ehw compare``), appending one JSON line per lifetime to
``results/learning_quality.jsonl`` (a seed already there is skipped, so the command resumes), then
prints the median interactions to 64 targets of both and their ratio. Not part of ``make bench``
(hours on this machine).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

OUT = Path("results/learning_quality.jsonl")


def _seeds(text: str) -> list[int]:
    """"101-120" or "7" -> the seeds (argparse type: a bad value is one error line)."""
    lo, _, hi = text.partition("-")
    try:
        seeds = list(range(int(lo), int(hi or lo) + 1))
    except ValueError:
        seeds = []
    if not seeds:
        raise argparse.ArgumentTypeError(f"expected FIRST-LAST or one seed, got {text!r}")
    return seeds


def run_one(seed: int, ga: str, max_interactions: int) -> dict:
    from cosim.online.run import OnlineConfig, make_run

    t0, c0 = time.perf_counter(), time.process_time()
    run = make_run(OnlineConfig(seed=seed, ga=ga, max_interactions=max_interactions), "reference")
    run.run()
    return {"seed": seed, "ga": ga, "targets": run.targets, "interactions": run.interactions,
            "generations": run.generations, "world_states": run.mirror.n_states,
            "max_interactions": max_interactions, "wall_s": round(time.perf_counter() - t0, 1),
            "cpu_s": round(time.process_time() - c0, 1)}


def report(rows: list[dict]) -> dict:
    out = {}
    for ga in ("host", "hardware"):
        mine = [r for r in rows if r["ga"] == ga]
        if mine:
            out[ga] = {"runs": len(mine), "reached_64": sum(r["targets"] >= 64 for r in mine),
                       "median_interactions": statistics.median(r["interactions"] for r in mine)}
    if "host" in out and "hardware" in out:
        out["ratio_hardware_to_host"] = round(
            out["hardware"]["median_interactions"] / out["host"]["median_interactions"], 3)
        by_seed = {(r["seed"], r["ga"]): r["interactions"] for r in rows}
        pairs = [(by_seed[s, "hardware"], by_seed[s, "host"]) for s, ga in by_seed if ga == "host"
                 and (s, "hardware") in by_seed]
        if pairs:  # per seed: the lifetimes are chaotic, so say how often and by how much
            out["paired_seeds"] = len(pairs)
            out["hardware_shorter"] = sum(hw < host for hw, host in pairs)
            out["geometric_mean_ratio"] = round(math.exp(statistics.fmean(
                math.log(hw / host) for hw, host in pairs)), 3)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.learning_quality", description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=_seeds, default="21-40")
    p.add_argument("--max-interactions", type=int, default=40_000)
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--ga", choices=("host", "hardware", "both"), default="both",
                   help="the GA(s) to run on each seed (default both)")
    args = p.parse_args(argv)
    rows = [json.loads(line) for line in args.out.read_text().splitlines()] if args.out.exists() else []
    done = {(r["seed"], r["ga"]) for r in rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        for ga in ("host", "hardware") if args.ga == "both" else (args.ga,):
            if (seed, ga) in done:
                continue
            row = run_one(seed, ga, args.max_interactions)
            rows.append(row)
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    print(json.dumps(report([r for r in rows if r["seed"] in args.seeds]), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
