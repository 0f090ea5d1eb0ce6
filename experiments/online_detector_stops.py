"""Round 11 (lead; docs/online.md, "Round 11"): the execution phase's failure detectors on a
controller that never fails. The hand-written baseline (``sim_world.baseline``) drives one on-line
lifetime with learning switched off: every stop a detector makes is counted (and the leg goes on,
as after a learning phase that kept the controller), so each stop is a false alarm of the
detector on this controller.

    python experiments/online_detector_stops.py [--seeds 1-8] [--set field=value ...] [--cycles]
    python experiments/online_detector_stops.py --seeds 1-8 --set loop_cycles=2
    python experiments/online_detector_stops.py --seeds 1-8 --pose-deg 1 --set loop_radius_mm=20 --learn

Prints one JSON line a seed (interactions to 64 targets, stops by detector) and a total line.
``--cycles``: the total line also lists the motion sequences of the cycle stops (the most common
first) and their odometry displacements, in 10 mm bins.

``--pose-deg TOL`` (measured and dropped, docs/online.md round 11): a cycle stop also needs the
round's commanded net rotation within TOL degrees of 0 (mod 360), i.e. the robot back in its pose,
not only its place. ``--learn``: the usual learning lifetimes (``--budget``, 20,000) instead of
the baseline's, one JSON line a seed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cosim.online.failures  # noqa: E402
from cosim.online.run import OnlineConfig, make_run  # noqa: E402
from experiments.online_round7 import parse_kv  # noqa: E402
from ga.motions import MOTION_ROTATION_DEG, Motion  # noqa: E402
from sim_world.baseline import baseline_table  # noqa: E402

SHORT = {m: "".join(w[0] for w in m.name.split("_")) for m in Motion}  # F, B, TL, TR, FL, ...


def parse_seeds(text: str) -> range:
    first, _, last = text.partition("-")
    return range(int(first), int(last or first) + 1)


class PoseCycles(cosim.online.failures.Cycles):
    """A cycle stop only when the round's commanded net rotation is within ``tol_deg`` of 0."""

    tol_deg = 1.0

    def observe(self, track) -> bool:
        if not super().observe(track):
            return False
        net = sum(float(MOTION_ROTATION_DEG[a]) for _, a in self.cycle) % 360.0
        if min(net, 360.0 - net) <= self.tol_deg:
            return True
        self.cycle = []
        return False


def with_pose_cycles(run, tol_deg: float):
    """Swap ``run``'s cycle detector for a PoseCycles with the same k and radius."""
    for i, d in enumerate(run.detectors):
        if isinstance(d, cosim.online.failures.Cycles):
            run.detectors[i] = PoseCycles(d.k, d.radius_mm)
            run.detectors[i].tol_deg = tol_deg
    return run


def baseline_lifetime(config: OnlineConfig, cycles: Counter | None = None,
                      pose_deg: float | None = None) -> tuple[object, Counter]:
    """One lifetime of ``config`` driven by the baseline, learning off: (run, stops by detector)."""
    table = baseline_table()
    run = with_pose_cycles(make_run(config, "reference"), pose_deg) if pose_deg is not None else \
        make_run(config, "reference")
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
    ap.add_argument("--pose-deg", type=float, help="cycle stops only back in pose (net rotation within this)")
    ap.add_argument("--learn", action="store_true", help="learning lifetimes, not the baseline's")
    ap.add_argument("--budget", type=int, default=20_000, help="interactions of a learning lifetime at most")
    args = ap.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        settings = parse_kv(args.set)
        configs = [OnlineConfig(seed=s, **settings) for s in seeds]
    except (ValueError, TypeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.learn:
        for config in configs:
            config = dataclasses.replace(config, max_interactions=args.budget)
            run = make_run(config, "reference")
            if args.pose_deg is not None:
                with_pose_cycles(run, args.pose_deg)
            run.run()
            print(json.dumps({"seed": config.seed, "settings": settings, "pose_deg": args.pose_deg,
                              "targets": run.targets, "interactions": run.interactions,
                              "phases": len(run.phases)}), flush=True)
        return 0
    total: Counter = Counter()
    cycles: Counter | None = Counter() if args.cycles else None
    for config in configs:
        run, stops = baseline_lifetime(config, cycles, args.pose_deg)
        total.update(stops)
        print(json.dumps({"seed": config.seed, "settings": settings, "targets": run.targets,
                          "interactions": run.interactions, "stops": dict(stops)}), flush=True)
    line = {"seeds": args.seeds, "settings": settings, "pose_deg": args.pose_deg, "stops": dict(total),
            "stops_per_lifetime": round(sum(total.values()) / len(configs), 1)}
    if cycles is not None:
        line["cycles"] = dict(cycles.most_common())
    print(json.dumps(line))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
