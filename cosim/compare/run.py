"""Every method on the same robot, arena and course over N seeds: the comparison table.

    ehw compare --seeds 5 [--first-seed 1] [--methods online,baseline,q-learning,...]
                [--shaping shaped,unshaped] [--jobs 2] [--cluster local|ADDRESS]
                [--arena default] [--out DIR] [--resume | --force] [--fresh] [--quiet]
                [--blind-bit B --blind-after-target T] [--config FILE]

Methods (``--methods``, default: all but the optional deep-RL ones):

* ``online``: the on-line model-based method (``cosim.online.run``; ``--online KEY=VALUE`` options).
* ``offline``: the off-line model-free method (``cosim.offline.run.run_offline``).
* ``baseline``: the hand-written reactive controller (``sim_world.baseline``) in the noisy world.
* ``q-learning``, ``dyna-q``, ``dyna-q+``, ``prioritized-sweeping``: tabular learners
  (``peers.tabular``) in one lifetime under the on-line protocol (``peers.lifetime``), once per
  ``--shaping`` (``unshaped``: target, crash and step rewards only; ``shaped``: plus the progress
  towards the ball by the camera's noisy range, SPEC section 4, which the 8-bit state does not contain). Hyper-parameters: ``peers.tabular.TUNED``,
  chosen by ``ehw tune`` (``cosim.compare.tune``) on ``peers.tabular.TUNING_SEEDS``.
* ``dqn``, ``ppo`` (optional, ``pip install .[rl]``): stable-baselines3 on the Gymnasium env
  (``peers.deep``), under the same protocol, every environment step counted. Hyper-parameters:
  ``peers.deep.tuned_hyper``, chosen by ``ehw tune`` on the same tuning seeds (shaped).

The lifetimes run through one executor (``cosim.compare.sweep``): a local process pool of ``--jobs``
workers, or a Dask cluster (``--cluster local`` starts one on the loopback interface,
``--cluster ADDRESS`` joins a scheduler). Finished lifetimes are cached under
``results/compare/cache`` by (method, config, seed), shared by every comparison: an interrupted
comparison resumes (``--fresh`` runs everything again). Every lifetime takes its randomness from
its seed only, so the table is the same whichever executor ran it.

Outputs, in the comparison's run folder (``results/compare/<date>-<time>-seeds<A>-<B>/``,
``results/compare/latest`` pointing at it; or ``--out DIR``): ``compare.json`` (per method:
interactions to 64 targets -- median, range, per seed --, crashes, targets reached where capped,
CPU seconds per lifetime, ..., and the ``config`` that ``--config`` takes back), ``compare.md``
(the table, with the paper's figures beside it and which seeds were used for tuning),
``compare.png``: targets reached against interactions for every method, the median over the seeds
and its range, and ``config.toml``.

With ``--blind-bit`` (adaptation, paper section 5.2): the on-line run blinds that IR bit after
target T and we count the interactions of the next 8 targets; the fixed off-line controller of the
same seed drives the same noisy, blinded world from the same relocation pose for 8 targets
(it cannot learn; a crash does not stop it, a leg time-out does).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from base.errors import UserError
from base.files import atomic_write_text
from cosim.compare.options import (  # noqa: F401  (online_options: re-exported)
    COMPARE_ROOT,
    add_arguments,
    check_args,
    check_resumed,
    online_options,
    read_report,
    recorded_options,
)
from cosim.compare.report import (  # noqa: F401  (re-exported: the names of cosim.compare.run)
    ADAPT_WINDOW,
    DEEP,
    DEFAULT_METHODS,
    METHODS,
    N_TARGETS,
    NAMES,
    OPTIONAL,
    PAPER,
    ROWS,
    SHAPINGS,
    TABULAR,
    _seed_text,
    add_limit,
    build_report,
    display_name,
    BOX_PLOT,
    markdown,
    seed_provenance,
    write_boxplot,
    write_plot,
)

# -- one lifetime per method (the only call sites of the runners) -----------------------------


def _effective_online(arena: str, online: dict | None) -> dict:
    """Every OnlineConfig field of an on-line row but the seed and arena: the options given and
    all the defaults, so the cache key of a lifetime changes when a default does (a lifetime
    cached under older defaults is never taken for one of the new)."""
    from cosim.online.config import OnlineConfig

    effective = OnlineConfig(arena=arena, **(online or {})).to_dict()
    del effective["seed"], effective["arena"]
    return effective


def _online(task: dict) -> dict:
    from cosim.online.report import write_results
    from cosim.online.run import OnlineConfig, make_run

    config = OnlineConfig(seed=task["seed"], arena=task["config"]["arena"], **task["config"]["online"])
    out = Path(task["out"]) / "model_based" / f"seed_{task['seed']}"
    run = make_run(config, out=out, resume=(out / "checkpoint.json").exists() and task.get("resume", False))
    run.run()
    summary = write_results(run, out, plots=False)
    result = {k: v for k, v in summary.items() if k not in ("phases", "targets")}
    result["target_interactions"] = [t["interactions"] for t in summary.get("targets", [])]
    return result


def _offline(task: dict) -> dict:
    from cosim.offline.run import run_offline

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
    from sim_world.world import DEFAULT_NOISE

    cap = max_interactions or MAX_INTERACTIONS
    sensing = {"range_sd": DEFAULT_NOISE.range_sd}  # the camera range the shaped peers learn from
    tasks = []
    for m in methods:
        if m == "online":
            rows = [("online", "online", {"arena": arena, "online": _effective_online(arena, online)})]
        elif m == "offline":
            rows = [("offline", "offline", {"arena": arena, "generations_cap": generations_cap})]
        elif m == "baseline":
            rows = [("baseline", "baseline", {"arena": arena})]
        elif m in TABULAR:
            import dataclasses

            from peers.tabular import tuned_config

            rows = [(f"{m}/{sh}", "tabular", {"arena": arena, "shaping": sh, "max_interactions": cap,
                                              "learner": dataclasses.asdict(tuned_config(m, sh)), **sensing})
                    for sh in shapings]
        elif m in DEEP:
            from peers.deep import tuned_hyper

            rows = [(f"{m}/{sh}", "deep", {"arena": arena, "shaping": sh, "max_interactions": cap,
                                           "hyper": tuned_hyper(m, sh), **sensing}) for sh in shapings]
        else:
            raise ValueError(f"unknown method {m!r}; choose from {', '.join(METHODS)}")
        for row, kind, config in rows:
            tasks += [{"method": row, "kind": kind, "seed": s, "config": config, "out": out, "resume": resume}
                      for s in seeds]
    return tasks


# -- adaptation ------------------------------------------------------------------------------


def fixed_controller_adaptation(genome_hex: str, arena: str, seed: int, bit: int, after: int,
                                window: int = ADAPT_WINDOW, max_leg_steps: int | None = None) -> dict:
    """The fixed off-line controller, IR bit ``bit`` blinded, from the pose that follows target
    ``after``: interactions for the next ``window`` targets (None if a leg times out), and
    ``states_with_bit``: how many of the states it met have that bit set (0 when blinded)."""
    from cosim.online.run import OnlineConfig
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


# -- command line (the options: cosim.compare.options; ``ehw compare`` adds --config) ------------


def render_only(path: Path) -> int:
    """``--render JSON``: rewrite compare.md and compare.png beside it (under its folder's lock)."""
    from base.runs import RunLock

    report = read_report(path, "--render")
    with RunLock(Path(path).parent):
        text = markdown(report)
        atomic_write_text(Path(path).parent / "compare.md", text)
        write_plot(report, Path(path).parent / "compare.png")
        write_boxplot(report, Path(path).parent / BOX_PLOT)
    print(text)
    return 0


def run_from_args(args) -> int:
    """The comparison of parsed options, every option checked first, its tables in a run folder
    (``cosim.compare.options``). Returns the exit status; a user error raises a UserError."""
    from base.options import write_config
    from base.runs import open_run

    if args.render is not None:
        return render_only(args.render)
    check_args(args)
    if args.adaptation_only:  # the comparison it extends: its folder, its compare.json
        run_dir = open_run(args.out, COMPARE_ROOT, resume=True, checkpoint="compare.json", markers=("compare.json",))
    else:
        run_dir = open_run(args.out, COMPARE_ROOT, resume=args.resume, force=args.force, checkpoint="config.toml",
                           markers=("compare.json",), label=f"seeds{args.seed_list[0]}-{args.seed_list[-1]}")
    with run_dir:
        folder = run_dir.path
        if args.resume and not args.adaptation_only:
            check_resumed(args, folder)
        if not args.adaptation_only:
            write_config(folder, recorded_options(args), {}, "compare")
        try:
            report = _compare(args, folder)
        except UserError:  # refused (e.g. no Dask scheduler): no folder stays; an interrupted
            run_dir.discard()  # one (Ctrl-C, kill) stays, for --resume
            raise
        run_dir.remove_stale()
    print(f"wrote {folder / 'compare.md'}, {folder / 'compare.json'}, {folder / 'compare.png'} and {BOX_PLOT} "
          f"({report['wall_time_s']:.0f} s)")
    return 0


def _compare(args, folder: Path) -> dict:
    """Run the lifetimes of checked ``args`` (cached ones come from the cache); write the tables."""
    from cosim.compare.sweep import Cache, executor, run_sweep

    seeds, online = args.seed_list, args.online_fields
    out = COMPARE_ROOT  # the lifetimes' own folders (checkpoints), shared like the cache
    common = dict(arena=args.arena, out=str(out), online=online, generations_cap=args.generations_cap,
                  max_interactions=args.max_interactions, resume=args.resume)
    tasks = [] if args.adaptation_only else make_tasks(args.methods_list, seeds, shapings=args.shapings, **common)

    def kept(task):
        n = args.limits.get(task["method"], args.limits.get(task["method"].partition("/")[0]))
        return n is None or task["seed"] < args.first_seed + n

    tasks = [t for t in tasks if kept(t)]
    if args.blind_bit is not None:
        adapt = {**online, "blind_bit": args.blind_bit, "blind_after_target": args.blind_after_target}
        tasks += [{**t, "method": "online-adaptation", "out": str(out / "adaptation")}
                  for t in make_tasks(["online"], seeds, **{**common, "online": adapt})]
    # The slow off-line runs first, so the pool stays busy.
    tasks.sort(key=lambda t: {"offline": 0, "online": 1, "deep": 2}.get(t["kind"], 3))
    cache = Cache(args.cache, read=not args.fresh)

    def report_progress(task, result, cached):
        if not args.quiet:
            print(f"{task['method']:28s} seed {task['seed']}: interactions {result.get('interactions'):,} "
                  f"targets {result.get('targets_reached')}" +
                  (" (cached)" if cached else f" ({result.get('task_wall_s', 0):.0f} s)"), flush=True)

    t0 = time.perf_counter()
    try:
        with executor(args.jobs, args.cluster) as pool:
            finished = run_sweep(run_task, tasks, pool, cache, on_result=report_progress)
    except ConnectionError as exc:
        raise UserError(f"--cluster {args.cluster!r}: {exc}") from None
    results: dict = {}
    adapted: dict = {}
    for task, result in zip(tasks, finished):
        if task["method"] == "online-adaptation":
            adapted[task["seed"]] = result
        else:
            results.setdefault(task["method"], {})[task["seed"]] = result
    if args.reused is not None:  # --reuse, --adaptation-only: the rows not run now
        for row, per in args.reused["per_seed"].items():
            if row not in results:
                results[row] = {s: v for s, v in per.items() if s in seeds}
        if args.adaptation_only:
            for s in seeds:
                path = out / "model_free" / f"seed_{s}" / "summary.json"
                if s in results.get("offline", {}) and path.exists():
                    results["offline"][s]["best_genome"] = json.loads(path.read_text()).get("best_genome")
    report = build_report(results, args.arena, seeds)
    if getattr(args, "planner_limit", False):
        from cosim.compare.limit import course_limit

        add_limit(report, course_limit(args.arena, cache))
    report["online_distance_rule"] = args.distance
    report["online_options"] = online
    report["seed_provenance"] = seed_provenance(results, seeds)
    report["box_plot"] = BOX_PLOT
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
    report["config"] = recorded_options(args) if not args.adaptation_only else \
        args.reused.get("config", recorded_options(args))
    atomic_write_text(folder / "compare.json", json.dumps(report, indent=1, allow_nan=False) + "\n")
    text = markdown(report)
    atomic_write_text(folder / "compare.md", text)
    write_plot(report, folder / "compare.png")
    write_boxplot(report, folder / BOX_PLOT)
    print(text)
    return report
