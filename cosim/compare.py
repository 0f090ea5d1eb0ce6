"""Both methods on the same arena over N seeds: the paper's comparison table (section 5).

    python -m cosim.compare --seeds 5 [--jobs 2] [--arena default] [--out results]
                            [--blind-bit B --blind-after-target T]

For seeds 1..N it runs the on-line model-based method (``cosim.online``, its default config), the
off-line model-free method (``cosim.offline.run_offline``) and the hand-written reactive baseline
(``sim_world.baseline``, in the noisy world), in a process pool (``--jobs``). It writes
``<out>/compare.md`` and ``<out>/compare.json``: interactions, generations, genetic operations,
world states and transitions for each method (median and range over the seeds), beside the
paper's figures, and the interaction ratio off-line / on-line.

With ``--blind-bit`` (adaptation, paper section 5.2): the on-line run blinds that IR bit after
target T and we count the interactions of the next 8 targets; the fixed off-line controller of the
same seed drives the same noisy, blinded world from the same relocation pose for 8 targets
(it cannot learn; a crash does not stop it, a leg time-out does).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

PAPER = {
    "online": {"interactions": 12_280, "generations": 485, "genetic_operations": 242_500,
               "world_states": 84, "transitions": 334},
    "offline": {"interactions": 3_283_269, "generations": 285, "genetic_operations": 5_700,
                "world_states": 122, "transitions": 744},
}
ROWS = ("interactions", "generations", "genetic_operations", "world_states", "transitions", "targets_reached")
ADAPT_WINDOW = 8


def _online(task: dict) -> dict:
    from cosim.online import OnlineConfig, make_run
    from cosim.online_report import write_results

    config = OnlineConfig(seed=task["seed"], arena=task["arena"], **task.get("online", {}))
    out = Path(task["out"]) / "model_based" / f"seed_{task['seed']}"
    run = make_run(config, out=out, resume=(out / "checkpoint.json").exists() and task.get("resume", False))
    run.run()
    summary = write_results(run, out, plots=False)
    return {k: v for k, v in summary.items() if k not in ("phases", "targets")}


def _offline(task: dict) -> dict:
    from cosim.offline import run_offline

    out = Path(task["out"]) / "model_free" / f"seed_{task['seed']}"
    kwargs = dict(out=out, arena=task["arena"], progress=False, plots=False,
                  resume=task.get("resume", False))
    if task.get("generations_cap"):
        kwargs["generations_cap"] = task["generations_cap"]
    summary = run_offline(task["seed"], **kwargs)
    return {k: v for k, v in summary.items() if k not in ("history",)}


def _baseline(task: dict) -> dict:
    from sim_world.baseline import baseline_table
    from sim_world.course import DEFAULT_MAX_LEG_STEPS, run_course
    from sim_world.world import DEFAULT_NOISE, World

    world = World(task["arena"], noise=DEFAULT_NOISE, seed=task["seed"])
    res = run_course(world, baseline_table(), DEFAULT_MAX_LEG_STEPS, n_targets=64)
    return {"interactions": res.steps, "targets_reached": res.targets_reached, "crashed": res.crashed,
            "timed_out": res.timed_out, "world_states": len(res.states),
            "transitions": len({(t[0], t[1]) for t in res.transitions}),
            "generations": 0, "genetic_operations": 0}


def fixed_controller_adaptation(genome_hex: str, arena: str, seed: int, bit: int, after: int,
                                window: int = ADAPT_WINDOW, max_leg_steps: int | None = None) -> dict:
    """The fixed off-line controller, IR bit ``bit`` blinded, from the pose that follows target
    ``after``: interactions for the next ``window`` targets (None if a leg times out)."""
    from cosim.online import OnlineConfig
    from ga.genome import rows_from_hex
    from ga.truth_table import truth_tables
    from sim_world.course import run_course
    from sim_world.world import DEFAULT_NOISE, Fault, World

    max_leg_steps = max_leg_steps or OnlineConfig().max_leg_steps
    world = World(arena, noise=DEFAULT_NOISE, faults=(Fault(at_step=0, bit=bit),), seed=seed)
    table = truth_tables(rows_from_hex(genome_hex), reflex=True)
    res = run_course(world, table, max_leg_steps, n_targets=window, start=(after - 1) % 64,
                     stop_on_crash=False)
    return {"targets": res.targets_reached, "interactions": res.steps, "crashes": res.crashes,
            "timed_out": res.timed_out,
            "interactions_for_next_targets": res.steps if res.targets_reached == window else None}


def _run(task: dict) -> tuple[str, int, dict]:
    fn = {"online": _online, "offline": _offline, "baseline": _baseline}[task["method"]]
    t0 = time.perf_counter()
    result = fn(task)
    result["task_wall_s"] = round(time.perf_counter() - t0, 2)
    return task["method"], task["seed"], result


def _stats(values) -> dict:
    values = [v for v in values if v is not None]
    if not values:
        return {"median": None, "min": None, "max": None}
    return {"median": float(np.median(values)), "min": min(values), "max": max(values)}


def _fmt(stat: dict) -> str:
    if stat["median"] is None:
        return "-"
    med = stat["median"]
    text = f"{med:,.0f}" if med == int(med) else f"{med:,.1f}"
    if stat["min"] != stat["max"]:
        text += f" ({stat['min']:,}-{stat['max']:,})"
    return text


def online_options(items: list[str]) -> dict:
    """``["distance_rule=covered", "loop_cycles=0"]`` -> OnlineConfig fields of the right types."""
    import dataclasses

    from cosim.online import OnlineConfig

    fields = {f.name: type(getattr(OnlineConfig(), f.name)) for f in dataclasses.fields(OnlineConfig)}
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in fields or key == "seed":
            raise SystemExit(f"--online wants KEY=VALUE with KEY an OnlineConfig field, got {item!r}")
        kind = fields[key]
        options[key] = (value.lower() in ("1", "true", "yes")) if kind is bool else \
            (value if kind in (str, type(None)) else kind(value))
    OnlineConfig(**options)  # refuse a bad value now, not in a worker
    return options


def build_report(results: dict, arena: str, seeds: list[int]) -> dict:
    report = {"arena": arena, "seeds": seeds, "paper": PAPER, "methods": {}, "per_seed": results}
    for method, per_seed in results.items():
        report["methods"][method] = {key: _stats([per_seed[s].get(key) for s in seeds if s in per_seed])
                                     for key in ROWS}
    on, off = results.get("online", {}), results.get("offline", {})
    ratios = [off[s]["interactions"] / on[s]["interactions"] for s in seeds
              if s in on and s in off and on[s]["interactions"]]
    if ratios:
        med_on = report["methods"]["online"]["interactions"]["median"]
        med_off = report["methods"]["offline"]["interactions"]["median"]
        report["interaction_ratio"] = {"of_medians": med_off / med_on, "per_seed": ratios,
                                       "median_per_seed": float(np.median(ratios))}
    return report


def markdown(report: dict) -> str:
    methods = [m for m in ("online", "offline", "baseline") if m in report["methods"]]
    names = {"online": "on-line model-based", "offline": "off-line model-free", "baseline": "reactive baseline"}
    head = "| | " + " | ".join(f"{names[m]} (median, range)" for m in methods) + \
        " | paper on-line | paper off-line |"
    lines = [f"# On-line model-based vs off-line model-free ({report['arena']} arena, seeds "
             f"{report['seeds'][0]}..{report['seeds'][-1]})", "", head,
             "|" + "---|" * (len(methods) + 3)]
    for key in ROWS:
        cells = [_fmt(report["methods"][m][key]) for m in methods]
        p_on = PAPER["online"].get(key, 64 if key == "targets_reached" else "")
        p_off = PAPER["offline"].get(key, 64 if key == "targets_reached" else "")
        lines.append(f"| {key.replace('_', ' ')} | " + " | ".join(cells) +
                     f" | {p_on:,} | {p_off:,} |")
    if report.get("online_distance_rule", "forward") != "forward":
        lines += ["", f"On-line runs with the option dist[a] = {report['online_distance_rule']} (the "
                  "paper's first reading, not SPEC section 7; docs/online.md, round 5)."]
    if report.get("online_options"):
        lines += ["", "On-line options: " + ", ".join(f"`{k}={v}`" for k, v in report["online_options"].items())
                  + " (defaults otherwise)."]
    if "interaction_ratio" in report:
        r = report["interaction_ratio"]
        lines += ["", f"Interaction ratio off-line / on-line: **{r['of_medians']:.0f}** (ratio of the "
                  f"medians; per seed {', '.join(f'{x:.0f}' for x in r['per_seed'])}); paper: 267 "
                  "(3,283,269 / 12,280), 'about 250'."]
    if "adaptation" in report:
        a = report["adaptation"]
        lines += ["", f"## Adaptation: IR bit {a['bit']} blinded after target {a['after']}", "",
                  f"Interactions for the next {ADAPT_WINDOW} targets (per seed; '-' = did not reach them):", "",
                  "| seed | on-line (learning) | fixed off-line controller |", "|---|---|---|"]
        for row in a["per_seed"]:
            on = row["online"] if row["online"] is not None else "-"
            off = row["offline"] if row["offline"] is not None else "-"
            lines.append(f"| {row['seed']} | {on} | {off} |")
    short = {m: sorted(int(s) for s, v in report["per_seed"].get(m, {}).items()
                       if v.get("targets_reached", 64) < 64) for m in methods}
    for m, seeds in short.items():
        if seeds:
            lines += ["", f"{names[m]}: seed(s) {', '.join(map(str, seeds))} stopped short of 64 targets "
                      "(a generation or interaction cap); their interactions are lower bounds."]
    online = report["per_seed"].get("online", {})
    if online:
        lines += ["", "On-line learning phases by reason (per seed): " + "; ".join(
            f"{s}: {v.get('phase_reasons')}" for s, v in sorted(online.items()))]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m cosim.compare", description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=5, help="seeds 1..N (default 5)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--arena", default="default")
    p.add_argument("--out", type=Path, default=Path("results"))
    p.add_argument("--methods", default="online,offline,baseline")
    p.add_argument("--generations-cap", type=int, default=None, help="off-line generation cap")
    p.add_argument("--resume", action="store_true", help="continue interrupted runs from their checkpoints")
    p.add_argument("--first-seed", type=int, default=1, help="the seeds are first..first+N-1 (default 1)")
    p.add_argument("--distance", choices=("covered", "forward"), default="forward",
                   help="dist[a] of the on-line fitness: forward = SPEC section 7, backward steps "
                        "cover 0; covered = the paper's first reading (docs/online.md, round 5)")
    p.add_argument("--online", action="append", default=[], metavar="KEY=VALUE",
                   help="an OnlineConfig field for the on-line runs, e.g. loop_cycles=0 (repeatable)")
    p.add_argument("--blind-bit", type=int, default=None)
    p.add_argument("--blind-after-target", type=int, default=None)
    p.add_argument("--adaptation-only", action="store_true",
                   help="with --blind-bit: run only the adaptation runs and add them to the existing "
                        "<out>/compare.json (the off-line controllers are read from its model_free runs)")
    p.add_argument("--reuse", action="store_true",
                   help="take the methods not run now (not in --methods) from the existing <out>/compare.json")
    p.add_argument("--render", type=Path, default=None, metavar="JSON",
                   help="only rewrite compare.md from an existing compare.json")
    args = p.parse_args(argv)
    if args.render is not None:
        text = markdown(json.loads(args.render.read_text()))
        (args.render.parent / "compare.md").write_text(text)
        print(text)
        return 0
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    online = {} if args.distance == "forward" else {"distance_rule": args.distance}
    online.update(online_options(args.online))
    methods = args.methods.split(",")
    out = args.out / "compare"
    base = {"arena": args.arena, "out": str(out), "resume": args.resume, "generations_cap": args.generations_cap}
    tasks = [] if args.adaptation_only else [{**base, "method": m, "seed": s, "online": online}
                                             for m in methods for s in seeds]
    if args.blind_bit is not None:
        tasks += [{**base, "method": "online", "seed": s, "adapt": True, "out": str(out / "adaptation"),
                   "online": {**online, "blind_bit": args.blind_bit, "blind_after_target": args.blind_after_target}}
                  for s in seeds]
    # The slow off-line runs first, so the pool stays busy.
    tasks.sort(key=lambda t: {"offline": 0, "online": 1, "baseline": 2}[t["method"]])
    results: dict = {m: {} for m in methods}
    adapted: dict = {}
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = [(t, pool.submit(_run, t)) for t in tasks]
        for task, fut in futures:
            method, seed, result = fut.result()
            (adapted if task.get("adapt") else results[method])[seed] = result
            print(f"{method:8s} seed {seed}: interactions {result.get('interactions'):,} "
                  f"targets {result.get('targets_reached')} ({result['task_wall_s']:.0f} s)", flush=True)
    if args.reuse and not args.adaptation_only and (args.out / "compare.json").exists():
        saved = json.loads((args.out / "compare.json").read_text())
        for m, per in saved["per_seed"].items():
            if m not in results or not results[m]:
                results[m] = {int(s): v for s, v in per.items() if int(s) in seeds}
    if args.adaptation_only:
        saved = json.loads((args.out / "compare.json").read_text())
        results = {m: {int(s): v for s, v in per.items()} for m, per in saved["per_seed"].items()}
        for s in seeds:
            path = out / "model_free" / f"seed_{s}" / "summary.json"
            if s in results.get("offline", {}) and path.exists():
                results["offline"][s]["best_genome"] = json.loads(path.read_text()).get("best_genome")
    report = build_report(results, args.arena, seeds)
    report["online_distance_rule"] = args.distance
    report["online_options"] = online
    if args.blind_bit is not None:
        rows = []
        for s in seeds:
            on = adapted[s].get("adaptation", {}).get("interactions_for_next_targets")
            off = None
            genome = results.get("offline", {}).get(s, {}).get("best_genome")
            if genome:
                off = fixed_controller_adaptation(genome, args.arena, s, args.blind_bit,
                                                  args.blind_after_target)["interactions_for_next_targets"]
            rows.append({"seed": s, "online": on, "offline": off})
        report["adaptation"] = {"bit": args.blind_bit, "after": args.blind_after_target, "per_seed": rows}
    report["wall_time_s"] = round(time.perf_counter() - t0, 1)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "compare.json").write_text(json.dumps(report, indent=1) + "\n")
    text = markdown(report)
    (args.out / "compare.md").write_text(text)
    print(text)
    print(f"wrote {args.out / 'compare.md'} and {args.out / 'compare.json'} ({report['wall_time_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
