"""``ehw limit``: how few interactions could any controller need? (issue 40, docs/limit.md)

    ehw limit [--arena NAME ...] [--cell 5] [--refine] [--reactive SECONDS] [--out DIR] [--force]

Per arena (default: every shipped arena) the omniscient planner (``sim_world.limit``) finds the
fewest crash-free interactions of each of the course's 64 legs; every path is replayed in the
noise-free world. ``--refine`` plans again with half the cell and reports the change (the
discretisation check). ``--reactive SECONDS`` also searches that long for the best fixed
256-state controller (``sim_world.reactive_limit``), the bound closer to the paper's robot.

Writes, in ``results/limit/<date>-<time>/`` (``results/limit/latest`` pointing at it) or
``--out``: ``limit.json`` (per arena: per leg the interactions, the motions, the search's size
and time; the totals), ``limit.md`` (the tables printed here), ``limit_<arena>.png`` (the planned
paths) and ``config.toml``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from base.errors import UserError
from base.options import add_common, option_keys, write_config
from cosim.cli.options import RESULTS


def limit_parser(p) -> None:
    from sim_world.course import DEFAULT_MAX_LEG_STEPS
    from sim_world.limit import DEFAULT_CELL_MM, HEURISTICS

    p.add_argument("--arena", action="append", default=None, metavar="NAME",
                   help="an arena name or .json file, repeatable (default: every shipped arena)")
    p.add_argument("--cell", type=float, default=DEFAULT_CELL_MM, metavar="MM",
                   help="the planner's position cell: one pose kept per cell and heading")
    p.add_argument("--heuristic", choices=HEURISTICS, default=HEURISTICS[0],
                   help="the A* lower bound: around the obstacles (geodesic) or the straight line")
    p.add_argument("--refine", action="store_true",
                   help="plan again with half the cell and report the change of the total")
    p.add_argument("--max-leg-steps", type=int, default=DEFAULT_MAX_LEG_STEPS,
                   help="the longest leg searched (and the reactive controller's leg time-out)")
    p.add_argument("--reactive", type=float, default=0.0, metavar="SECONDS",
                   help="also search this long per arena for the best fixed 256-state controller")
    p.add_argument("--temperature", type=float, default=5.0,
                   help="the reactive search's starting annealing temperature (0: hill climbing)")
    p.add_argument("--seed", type=int, default=1, help="the reactive search's seed")
    add_common(p, seed=False, resume=False,
               out_help="the run folder (default: a fresh results/limit/<date>-<time>/, with "
                        "results/limit/latest pointing at it)")


def _check(args) -> None:
    from sim_world.limit import MIN_CELL_MM

    if not (math.isfinite(args.cell) and args.cell >= MIN_CELL_MM):
        raise UserError(f"--cell must be at least {MIN_CELL_MM:g} mm, got {args.cell!r}")
    if args.refine and args.cell / 2 < MIN_CELL_MM:
        raise UserError(f"--refine halves --cell to {args.cell / 2:g} mm, below {MIN_CELL_MM:g} mm")
    if not 1 <= args.max_leg_steps <= 10_000:
        raise UserError(f"--max-leg-steps must be in 1..10000, got {args.max_leg_steps!r}")
    for name in ("reactive", "temperature"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value >= 0):
            raise UserError(f"--{name} must be a finite number >= 0, got {value!r}")


def _plan(arena, cell, args):
    from tqdm import tqdm

    from sim_world.limit import plan_course

    with tqdm(total=64, desc=f"{arena.name}, {cell:g} mm", unit="leg", disable=args.quiet, leave=False) as bar:
        return plan_course(arena, cell, args.heuristic, args.max_leg_steps, progress=lambda leg: bar.update())


def _reactive(arena, args) -> dict:
    from tqdm import tqdm

    from sim_world.reactive_limit import search_table

    with tqdm(total=round(args.reactive), desc=f"{arena.name}, reactive", unit="s", disable=args.quiet,
              leave=False) as bar:
        def shown(elapsed, failed, steps):
            bar.n = min(bar.total, round(elapsed))
            bar.set_postfix(failed=failed, interactions=steps)

        found = search_table(arena, args.reactive, np.random.default_rng(args.seed), max_leg_steps=args.max_leg_steps,
                             temperature=args.temperature, progress=shown)
    return {**found.to_json(), "seed": args.seed, "temperature": args.temperature}


def _straight_line_bound(arena) -> int:
    """The sum over the legs of ceil((distance to the ball - target radius) / step): no controller
    can do better."""
    from sim_world.limit import StepBound, course_starts

    starts = np.array([p[:2] for p in course_starts(arena)])
    return int(StepBound(arena, "euclid").steps(starts[:, 0], starts[:, 1]).sum())


def _plot(arena, plan, path: Path) -> None:
    from sim_world.render import plot_trajectory
    from sim_world.world import World

    world, trajectory = World(arena), []
    for leg in plan.legs:
        world.place(leg.start)
        trajectory.append((*leg.start, "relocate"))
        for motion in leg.motions:
            out = world.step(motion)
            trajectory.append((*world.pose, "target" if out.reached else ""))
    plot_trajectory(arena, trajectory, path, title=f"the limit, {arena.name} arena: {plan.total:,} interactions "
                                                   f"over {len(plan.legs)} legs (cell {plan.cell_mm:g} mm)")


def markdown(report: dict) -> str:
    arenas = report["arenas"]
    lines = ["# The limit: the fewest interactions to 64 targets (omniscient planner, noise-free)", "",
             "| arena | limit (planner) | straight-line bound | refined cell: total (change) | "
             "best fixed 256-state controller | its ratio to the limit | planner wall s |",
             "|---|---|---|---|---|---|---|"]
    for name, a in arenas.items():
        refined = a.get("refined")
        ref = f"{refined['total_interactions']:,} at {refined['cell_mm']:g} mm ({refined['change']:+.2%})" \
            if refined else "-"
        re = a.get("reactive")
        rtext = f"{re['interactions']:,} ({re['failed_legs']} failed legs)" if re else "-"
        ratio = f"{re['interactions'] / a['total_interactions']:.2f}" if re and a["total_interactions"] else "-"
        lines.append(f"| {name} | {a['total_interactions']:,} | {a['straight_line_bound']:,} | {ref} | {rtext} | "
                     f"{ratio} | {a['seconds']:.0f} |")
    lines += ["", f"Cell {report['cell_mm']:g} mm, heuristic {report['heuristic']}; every path replayed in the "
              "noise-free world: no crash, target reached. Wall time "
              f"{report['wall_time_s']:,.0f} s.", "", "Interactions per leg:", "",
              "| leg | " + " | ".join(arenas) + " |", "|---" * (len(arenas) + 1) + "|"]
    for i in range(max(len(a["per_leg"]) for a in arenas.values())):
        cells = [str(a["per_leg"][i]["interactions"]) if i < len(a["per_leg"]) else "" for a in arenas.values()]
        lines.append(f"| {i} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def cmd_limit(args, extras: dict, sub=None) -> int:
    from base.files import atomic_write_json, atomic_write_text
    from base.runs import open_run
    from sim_world.arena import ARENAS, load_arena

    _check(args)
    arenas = [load_arena(name) for name in (args.arena or ARENAS)]  # every file checked first
    with open_run(args.out, RESULTS / "limit", force=args.force, checkpoint=None,
                  markers=("limit.json",), label="cell" + f"{args.cell:g}".replace(".", "_")) as run_dir:
        folder = run_dir.path
        options = {k: getattr(args, k) for k in option_keys(sub)} if sub is not None else {}
        write_config(folder, {k: (str(v) if isinstance(v, Path) else v) for k, v in options.items()
                              if v is not None}, {}, "limit")
        t0 = time.perf_counter()
        report = {"cell_mm": args.cell, "heuristic": args.heuristic, "max_leg_steps": args.max_leg_steps,
                  "arenas": {}}
        for arena in arenas:
            plan = _plan(arena, args.cell, args)
            if plan.total is None:
                missing = [i for i, leg in enumerate(plan.legs) if leg.interactions is None]
                raise UserError(f"arena {arena.name!r}: no crash-free path within --max-leg-steps "
                                f"{args.max_leg_steps} for legs {missing}")
            entry = {**plan.to_json(), "straight_line_bound": _straight_line_bound(arena)}
            if args.refine:
                fine = _plan(arena, args.cell / 2, args)
                entry["refined"] = {"cell_mm": fine.cell_mm, "total_interactions": fine.total,
                                    "change": (fine.total - plan.total) / plan.total, "seconds": round(fine.seconds, 1),
                                    "per_leg": [leg.interactions for leg in fine.legs]}
            if args.reactive:
                entry["reactive"] = _reactive(arena, args)
            report["arenas"][arena.name] = entry
            _plot(arena, plan, folder / f"limit_{arena.name}.png")
            if not args.quiet:
                print(f"{arena.name}: limit {plan.total:,} interactions over {len(plan.legs)} legs "
                      f"({plan.seconds:.0f} s)", flush=True)
        report["wall_time_s"] = round(time.perf_counter() - t0, 1)
        atomic_write_json(folder / "limit.json", report, indent=1)
        text = markdown(report)
        atomic_write_text(folder / "limit.md", text)
        run_dir.remove_stale()
    print(text)
    print(f"wrote {folder / 'limit.json'}, {folder / 'limit.md'} and the limit_<arena>.png plots")
    return 0
