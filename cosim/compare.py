"""Every method on the same robot, arena and course over N seeds: the comparison table.

    python -m cosim.compare --seeds 5 [--first-seed 1] [--methods online,baseline,q-learning,...]
                            [--shaping shaped,unshaped] [--jobs 2] [--cluster local|ADDRESS]
                            [--arena default] [--out results] [--fresh]
                            [--blind-bit B --blind-after-target T]

Methods (``--methods``, default: all but the optional deep-RL ones):

* ``online``: the on-line model-based method (``cosim.online``; ``--online KEY=VALUE`` options).
* ``offline``: the off-line model-free method (``cosim.offline.run_offline``).
* ``baseline``: the hand-written reactive controller (``sim_world.baseline``) in the noisy world.
* ``q-learning``, ``dyna-q``, ``prioritized-sweeping``: tabular learners (``peers.tabular``) in
  one lifetime under the on-line protocol (``peers.lifetime``), once per ``--shaping``
  (``unshaped``: target, crash and step rewards only; ``shaped``: plus the progress towards the
  ball, a distance the 8-bit state does not contain). Hyper-parameters: ``peers.tabular.TUNED``,
  chosen by experiments/tune_tabular.py on its tuning seeds.
* ``dqn``, ``ppo`` (optional, ``pip install .[rl]``): stable-baselines3 on the Gymnasium env
  (``peers.deep``), under the same protocol, every environment step counted. Hyper-parameters:
  ``peers.deep.tuned_hyper``, chosen by experiments/tune_deep.py on the same tuning seeds.

The lifetimes run through one executor (``cosim.sweep``): a local process pool of ``--jobs``
workers, or a Dask cluster (``--cluster local`` starts one on the loopback interface,
``--cluster ADDRESS`` joins a scheduler). Finished lifetimes are cached under
``<out>/compare/cache`` by (method, config, seed): an interrupted comparison resumes (``--fresh``
runs everything again). Every lifetime takes its randomness from its seed only, so the table is
the same whichever executor ran it.

Outputs: ``<out>/compare.json`` (per method: interactions to 64 targets -- median, range, per
seed --, crashes, targets reached where capped, CPU seconds per lifetime, ...), ``<out>/compare.md``
(the table, with the paper's figures beside it and which seeds were used for tuning), and
``<out>/compare.png``: targets reached against interactions for every method, the median over
the seeds and its range.

With ``--blind-bit`` (adaptation, paper section 5.2): the on-line run blinds that IR bit after
target T and we count the interactions of the next 8 targets; the fixed off-line controller of the
same seed drives the same noisy, blinded world from the same relocation pose for 8 targets
(it cannot learn; a crash does not stop it, a leg time-out does).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from cosim.runs import atomic_write_text
from cosim.compare_report import (  # noqa: F401  (re-exported: the names of cosim.compare)
    ADAPT_WINDOW, DEEP, DEFAULT_METHODS, METHODS, N_TARGETS, NAMES, OPTIONAL, PAPER, ROWS, SHAPINGS, TABULAR,
    _seed_text, build_report, display_name, markdown, write_plot,
)


# -- one lifetime per method (the only call sites of the runners) -----------------------------


def _online(task: dict) -> dict:
    from cosim.online import OnlineConfig, make_run
    from cosim.online_report import write_results

    config = OnlineConfig(seed=task["seed"], arena=task["config"]["arena"], **task["config"]["online"])
    out = Path(task["out"]) / "model_based" / f"seed_{task['seed']}"
    run = make_run(config, out=out, resume=(out / "checkpoint.json").exists() and task.get("resume", False))
    run.run()
    summary = write_results(run, out, plots=False)
    result = {k: v for k, v in summary.items() if k not in ("phases", "targets")}
    result["target_interactions"] = [t["interactions"] for t in summary.get("targets", [])]
    return result


def _offline(task: dict) -> dict:
    from cosim.offline import run_offline

    cfg = task["config"]
    out = Path(task["out"]) / "model_free" / f"seed_{task['seed']}"
    kwargs = dict(out=out, arena=cfg["arena"], progress=False, plots=False, resume=task.get("resume", False))
    if cfg.get("generations_cap"):
        kwargs["generations_cap"] = cfg["generations_cap"]
    summary = run_offline(task["seed"], **kwargs)
    result = {k: v for k, v in summary.items() if k not in ("history",)}
    result["target_interactions"] = offline_curve(json.loads((out / "history.json").read_text()))
    result["crashes"] = None  # crashes happen inside the GA's evaluations (each ends the run)
    return result


def offline_curve(history: list[dict]) -> list[int]:
    """The off-line run's curve: for k = 1, 2, ... the interactions spent (by every controller
    evaluated so far) when the best controller first reached k targets."""
    curve, best = [], 0
    for entry in history:
        while best < entry["best_targets"]:
            best += 1
            curve.append(entry["interactions"])
    return curve


def _baseline(task: dict) -> dict:
    from peers.lifetime import seeds
    from sim_world.baseline import baseline_table
    from sim_world.course import DEFAULT_MAX_LEG_STEPS, run_course
    from sim_world.world import DEFAULT_NOISE, World

    world_seed, _ = seeds(task["seed"])  # the noise stream of the other methods' seed
    world = World(task["config"]["arena"], noise=DEFAULT_NOISE, seed=world_seed)
    res = run_course(world, baseline_table(), DEFAULT_MAX_LEG_STEPS, n_targets=N_TARGETS)
    return {"interactions": res.steps, "targets_reached": res.targets_reached, "crashed": res.crashed,
            "crashes": res.crashes, "timed_out": res.timed_out, "world_states": len(res.states),
            "transitions": len({(t[0], t[1]) for t in res.transitions}),
            "generations": 0, "genetic_operations": 0,
            "target_interactions": np.cumsum(res.leg_steps).tolist()}


def _tabular(task: dict) -> dict:
    from peers.lifetime import run_lifetime
    from peers.tabular import LearnerConfig

    cfg = task["config"]
    return run_lifetime(task["method"].split("/")[0], task["seed"], shaping=cfg["shaping"],
                        config=LearnerConfig(**cfg["learner"]), arena=cfg["arena"],
                        max_interactions=cfg["max_interactions"])


def _deep(task: dict) -> dict:
    from peers.deep import run_deep_lifetime

    cfg = task["config"]
    return run_deep_lifetime(task["method"].split("/")[0], task["seed"], shaping=cfg["shaping"],
                             hyper=cfg["hyper"], arena=cfg["arena"], max_interactions=cfg["max_interactions"])


RUNNERS = {"online": _online, "offline": _offline, "baseline": _baseline, "tabular": _tabular, "deep": _deep}


def run_task(task: dict) -> dict:
    """One lifetime (a sweep task); adds its CPU and wall seconds."""
    c0, t0 = time.process_time(), time.perf_counter()
    result = RUNNERS[task["kind"]](task)
    result["cpu_s"] = round(time.process_time() - c0, 2)
    result["task_wall_s"] = round(time.perf_counter() - t0, 2)
    return result


def make_tasks(methods, seeds, *, arena: str, out: str, shapings=SHAPINGS, online: dict | None = None,
               generations_cap: int | None = None, max_interactions: int | None = None,
               resume: bool = False) -> list[dict]:
    """The sweep's tasks: one per (row, seed); ``config`` holds what determines the result."""
    from peers.lifetime import MAX_INTERACTIONS

    cap = max_interactions or MAX_INTERACTIONS
    tasks = []
    for m in methods:
        if m == "online":
            rows = [("online", "online", {"arena": arena, "online": dict(online or {})})]
        elif m == "offline":
            rows = [("offline", "offline", {"arena": arena, "generations_cap": generations_cap})]
        elif m == "baseline":
            rows = [("baseline", "baseline", {"arena": arena})]
        elif m in TABULAR:
            import dataclasses

            from peers.tabular import tuned_config

            rows = [(f"{m}/{sh}", "tabular", {"arena": arena, "shaping": sh, "max_interactions": cap,
                                              "learner": dataclasses.asdict(tuned_config(m, sh))})
                    for sh in shapings]
        elif m in DEEP:
            from peers.deep import tuned_hyper

            rows = [(f"{m}/{sh}", "deep", {"arena": arena, "shaping": sh, "max_interactions": cap,
                                           "hyper": tuned_hyper(m, sh)}) for sh in shapings]
        else:
            raise ValueError(f"unknown method {m!r}; choose from {', '.join(METHODS)}")
        for row, kind, config in rows:
            tasks += [{"method": row, "kind": kind, "seed": s, "config": config, "out": out, "resume": resume}
                      for s in seeds]
    return tasks


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


# -- adaptation ------------------------------------------------------------------------------


def fixed_controller_adaptation(genome_hex: str, arena: str, seed: int, bit: int, after: int,
                                window: int = ADAPT_WINDOW, max_leg_steps: int | None = None) -> dict:
    """The fixed off-line controller, IR bit ``bit`` blinded, from the pose that follows target
    ``after``: interactions for the next ``window`` targets (None if a leg times out), and
    ``states_with_bit``: how many of the states it met have that bit set (0 when blinded)."""
    from cosim.online import OnlineConfig
    from ga.genome import rows_from_hex
    from ga.truth_table import truth_tables
    from sim_world.course import run_course
    from sim_world.world import DEFAULT_NOISE, Fault, World

    max_leg_steps = max_leg_steps or OnlineConfig().max_leg_steps
    world = World(arena, noise=DEFAULT_NOISE, faults=(Fault(at_step=0, bit=bit),), seed=seed)
    table = truth_tables(rows_from_hex(genome_hex), reflex=True)
    res = run_course(world, table, max_leg_steps, n_targets=window, start=(after - 1) % N_TARGETS,
                     stop_on_crash=False)
    return {"targets": res.targets_reached, "interactions": res.steps, "crashes": res.crashes,
            "timed_out": res.timed_out, "states_with_bit": sum(1 for s in res.states if s >> bit & 1),
            "interactions_for_next_targets": res.steps if res.targets_reached == window else None}


# -- command line ----------------------------------------------------------------------------


def _error(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return 2


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cosim.compare", description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=5, help="seeds first..first+N-1 (default 5)")
    p.add_argument("--first-seed", type=int, default=1, help="the first seed (default 1)")
    p.add_argument("--methods", default=",".join(DEFAULT_METHODS),
                   help=f"comma-separated, from {','.join(METHODS)} (default: all but {','.join(OPTIONAL)})")
    p.add_argument("--shaping", default=",".join(SHAPINGS),
                   help="reward variants of the RL methods: shaped, unshaped or both (default both)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--cluster", default=None, metavar="local|ADDRESS",
                   help="run the lifetimes on Dask: 'local' starts a LocalCluster of --jobs workers on "
                        "127.0.0.1; an address (tcp://host:8786) joins that scheduler")
    p.add_argument("--arena", default="default")
    p.add_argument("--out", type=Path, default=Path("results"))
    p.add_argument("--fresh", action="store_true", help="ignore cached lifetimes (they are overwritten)")
    p.add_argument("--cache", type=Path, default=None, help="the lifetime cache (default <out>/compare/cache)")
    p.add_argument("--limit-seeds", action="append", default=[], metavar="ROW=N",
                   help="run only the first N seeds for ROW, a method or method/shaping "
                        "(e.g. offline=5,q-learning/unshaped=10): slow rows on fewer seeds")
    p.add_argument("--max-interactions", type=int, default=None,
                   help="cap of an RL lifetime (default 100,000, as the on-line run's)")
    p.add_argument("--generations-cap", type=int, default=None, help="off-line generation cap")
    p.add_argument("--resume", action="store_true",
                   help="on-line/off-line runs not in the cache continue from their checkpoints")
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
                   help="only rewrite compare.md and compare.png from an existing compare.json")
    return p


def _load_report(path: Path) -> dict:
    report = json.loads(path.read_text())
    report["per_seed"] = {m: {int(s): v for s, v in per.items()} for m, per in report["per_seed"].items()}
    return report


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.render is not None:
        if not args.render.exists():
            return _error(f"no such file: {args.render}")
        report = _load_report(args.render)
        text = markdown(report)
        atomic_write_text(args.render.parent / "compare.md", text)
        write_plot(report, args.render.parent / "compare.png")
        print(text)
        return 0
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad:
        return _error(f"unknown method(s) {', '.join(bad)}; choose from {', '.join(METHODS)}")
    shapings = [s.strip() for s in args.shaping.split(",") if s.strip()]
    if not shapings or any(s not in SHAPINGS for s in shapings):
        return _error(f"--shaping takes {' and/or '.join(SHAPINGS)}, got {args.shaping!r}")
    if any(m in DEEP for m in methods):
        try:
            import stable_baselines3  # noqa: F401
        except ImportError:
            return _error("dqn and ppo need the optional extra: pip install -e '.[rl]'")
    if args.seeds < 1 or args.jobs < 1:
        return _error("--seeds and --jobs must be at least 1")
    if (args.blind_bit is None) != (args.blind_after_target is None):
        return _error("--blind-bit and --blind-after-target go together")
    if args.adaptation_only and not (args.out / "compare.json").exists():
        return _error(f"--adaptation-only needs an existing {args.out / 'compare.json'}")
    from cosim.sweep import Cache, executor, run_sweep

    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    online = {} if args.distance == "forward" else {"distance_rule": args.distance}
    online.update(online_options(args.online))
    out = args.out / "compare"
    common = dict(arena=args.arena, out=str(out), online=online, generations_cap=args.generations_cap,
                  max_interactions=args.max_interactions, resume=args.resume)
    tasks = [] if args.adaptation_only else make_tasks(methods, seeds, shapings=shapings, **common)
    limits = {}
    for item in ",".join(args.limit_seeds).split(","):
        row, sep, n = item.strip().partition("=")
        if not item.strip():
            continue
        if not sep or not n.isdigit() or row.partition("/")[0] not in METHODS:
            return _error(f"--limit-seeds wants ROW=N with ROW a method or method/shaping, got {item!r}")
        limits[row] = int(n)

    def kept(task):
        n = limits.get(task["method"], limits.get(task["method"].partition("/")[0]))
        return n is None or task["seed"] < args.first_seed + n

    tasks = [t for t in tasks if kept(t)]
    if args.blind_bit is not None:
        adapt = {**online, "blind_bit": args.blind_bit, "blind_after_target": args.blind_after_target}
        tasks += [{**t, "method": "online-adaptation", "out": str(out / "adaptation")}
                  for t in make_tasks(["online"], seeds, **{**common, "online": adapt})]
    # The slow off-line runs first, so the pool stays busy.
    tasks.sort(key=lambda t: {"offline": 0, "online": 1, "deep": 2}.get(t["kind"], 3))
    cache = Cache(args.cache or out / "cache", read=not args.fresh)

    def report_progress(task, result, cached):
        print(f"{task['method']:28s} seed {task['seed']}: interactions {result.get('interactions'):,} "
              f"targets {result.get('targets_reached')}" +
              (" (cached)" if cached else f" ({result.get('task_wall_s', 0):.0f} s)"), flush=True)

    t0 = time.perf_counter()
    try:
        with executor(args.jobs, args.cluster) as pool:
            finished = run_sweep(run_task, tasks, pool, cache, on_result=report_progress)
    except ConnectionError as exc:
        return _error(str(exc))
    results: dict = {}
    adapted: dict = {}
    for task, result in zip(tasks, finished):
        if task["method"] == "online-adaptation":
            adapted[task["seed"]] = result
        else:
            results.setdefault(task["method"], {})[task["seed"]] = result
    if (args.reuse or args.adaptation_only) and (args.out / "compare.json").exists():
        saved = _load_report(args.out / "compare.json")
        for row, per in saved["per_seed"].items():
            if row not in results:
                results[row] = {s: v for s, v in per.items() if s in seeds}
        if args.adaptation_only:
            for s in seeds:
                path = out / "model_free" / f"seed_{s}" / "summary.json"
                if s in results.get("offline", {}) and path.exists():
                    results["offline"][s]["best_genome"] = json.loads(path.read_text()).get("best_genome")
    report = build_report(results, args.arena, seeds)
    report["online_distance_rule"] = args.distance
    report["online_options"] = online
    from peers.tabular import TUNED, TUNING_SEEDS
    from peers.deep import TUNED as DEEP_TUNED

    if any(r.partition("/")[0] in TABULAR + DEEP for r in results):
        used = sorted(set(seeds) & set(TUNING_SEEDS))
        report["tuning"] = (f"The tabular learners' hyper-parameters were chosen on seeds {_seed_text(TUNING_SEEDS)} "
                            f"(experiments/tune_tabular.py){'' if TUNED else ' -- not yet run: defaults'}; "
                            + (f"**seeds {used} were used for tuning**." if used else
                               "none of the reported seeds was.") +
                            " DQN and PPO: stable-baselines3's defaults with the settings in peers/deep.py, their "
                            "learning rate (and DQN's exploration fraction) chosen on the same seeds "
                            "(experiments/tune_deep.py)" + ("" if DEEP_TUNED else " -- not yet run") + ".")
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
    report["executor"] = (f"Dask cluster {args.cluster}" if args.cluster else "local process pool") + \
        f", {args.jobs} worker(s)"
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "compare.json", json.dumps(report, indent=1) + "\n")
    text = markdown(report)
    atomic_write_text(args.out / "compare.md", text)
    write_plot(report, args.out / "compare.png")
    print(text)
    print(f"wrote {args.out / 'compare.md'}, {args.out / 'compare.json'} and {args.out / 'compare.png'} "
          f"({report['wall_time_s']:.0f} s)")
    return 0


if __name__ == "__main__":  # ``ehw compare`` adds the input checks and the lock
    raise SystemExit(main())
