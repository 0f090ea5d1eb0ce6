"""Round 11 (lead; docs/online.md, "Round 11"): the execution phase's failure detectors on a
controller that never fails. The hand-written baseline (``sim_world.baseline``) drives one on-line
lifetime with learning switched off: every stop a detector makes is counted (and the leg goes on,
as after a learning phase that kept the controller), so each stop is a false alarm of the
detector on this controller.

    python experiments/online_detector_stops.py [--seeds 1-8] [--set field=value ...] [--cycles]
    python experiments/online_detector_stops.py --seeds 1-8 --set loop_cycles=2

Prints one JSON line a seed (interactions to 64 targets, stops by detector) and a total line.
``--cycles``: the total line also lists the motion sequences of the cycle stops (the most common
first) and their odometry displacements, in 10 mm bins.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim.online import OnlineConfig, make_run  # noqa: E402
from experiments.online_round7 import parse_kv  # noqa: E402
from ga.motions import Motion  # noqa: E402
from sim_world.baseline import baseline_table  # noqa: E402

SHORT = {m: "".join(w[0] for w in m.name.split("_")) for m in Motion}  # F, B, TL, TR, FL, ...


def parse_seeds(text: str) -> range:
    first, _, last = text.partition("-")
    return range(int(first), int(last or first) + 1)


def baseline_lifetime(config: OnlineConfig, cycles: Counter | None = None) -> tuple[object, Counter]:
    """One lifetime of ``config`` driven by the baseline, learning off: (run, stops by detector)."""
    table = baseline_table()
    run = make_run(config, "reference")
    run.controller.motion = lambda s: int(table[s])
    run.started = True  # no random first controller
    stops: Counter = Counter()
    cycle_detector = next((d for d in run.detectors if d.name == "cycles"), None)

    def learn(reason, steps, state, motion, detector=""):
        stops[f"{reason}:{detector}" if detector else reason] += 1
        if cycles is not None and detector == "cycles":
            pairs = cycle_detector.cycle
            moved = run.track.moved(max(-len(pairs) - 1, -len(run.track.places)))
            cycles[" ".join(SHORT[Motion(a)] for _, a in pairs)] += 1
            cycles[f"moved {int(moved // 10) * 10} mm"] += 1
        run.phases.append({"reason": reason})

    run.learn = learn
    return run.run(), stops


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-8", help="a seed or a range, e.g. 1-8")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="an OnlineConfig field (JSON value), e.g. loop_cycles=2")
    ap.add_argument("--cycles", action="store_true", help="list the cycle stops' motions")
    args = ap.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        settings = parse_kv(args.set)
        configs = [OnlineConfig(seed=s, **settings) for s in seeds]
    except (ValueError, TypeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    total: Counter = Counter()
    cycles: Counter | None = Counter() if args.cycles else None
    for config in configs:
        run, stops = baseline_lifetime(config, cycles)
        total.update(stops)
        print(json.dumps({"seed": config.seed, "settings": settings, "targets": run.targets,
                          "interactions": run.interactions, "stops": dict(stops)}), flush=True)
    line = {"seeds": args.seeds, "settings": settings, "stops": dict(total),
            "stops_per_lifetime": round(sum(total.values()) / len(configs), 1)}
    if cycles is not None:
        line["cycles"] = dict(cycles.most_common())
    print(json.dumps(line))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
