"""The ``ehw sim`` and ``ehw offline`` commands: a run folder (``base.runs``), the run's
complete config (``config.toml``, from options and ``--config``), every option checked before any
work, and on ``--resume`` the config stored with the run."""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import sys
from pathlib import Path

from base.errors import UserError
from base.files import atomic_write_json
from base.options import PROG, add_common, fill_help, option_keys, write_config
from base.runs import open_run
from cosim.cli.options import LINK_BACKENDS, RESULTS, add_hdl_options, hdl_environment, resolve_hdl_settings
from cosim.cli.report import add_report_flag, report_at_end
from cosim.online.config import OPTIONS
from cosim.online.learning_phase import check_learning_backend

# -- sim: the on-line experiment ------------------------------------------------------------------

# The on-line options: cosim.cli.online (add_arguments, config_from_args); the reporting:
# cosim.online.report; the cocotb launcher: cosim.launch.cocotb_sim (imported when used: it brings
# cocotb's runner).


def _online_cli():
    from cosim.cli import online as online_cli

    return online_cli.add_arguments, online_cli.config_from_args


def _cocotb_launcher():
    """``run_online_cocotb``: the run inside a cocotb test on the Verilog."""
    from cosim.launch.cocotb_sim import run_online_cocotb

    return run_online_cocotb


def _online_reporting():
    from cosim.online import report as online_report

    return online_report.write_results, online_report.summary_table


# The OnlineConfig fields whose option has another name (config file key -> the option's dest).
SIM_DEST_OF = {field: flag.lstrip("-") for field, flag in OPTIONS.items()}
SIM_RUN_OPTIONS = {"backend": str, "simulator": str | None, "hdl_sample": int | None,
                   "waves": bool | None, "clock_hz": float | None, "port": str | None,
                   "port2": str | None, "baud": float | None, "line_faults": str | None}


def sim_parser(p) -> None:
    add_arguments, _ = _online_cli()
    add_arguments(p)
    fill_help(p, "the run config's {dest} (cosim.online.config.OnlineConfig)")
    for action in p._actions:  # the options are checked once more on the config they make
        if action.dest == "no_plots":
            action.help = "write no figures (an earlier run's figures are removed all the same)"
        if action.dest == "no_progress":
            action.help = "no progress bar (as --quiet)"
        if action.dest == "backend":
            action.help = ("the boards: the NumPy reference, Amaranth's simulator, cocotb on the "
                           "Verilog (see --simulator, --hdl-sample), real boards on a serial port "
                           "(see --port), or the link top in Verilator over a simulated line (uart)")
    add_common(p, out_help="the run folder (default: a fresh results/model_based/<date>-<time>-seed<S>/, "
                            "with results/model_based/latest pointing at it)")
    add_hdl_options(p)
    add_report_flag(p)


def _flag_name(field: str) -> str:
    return "--" + {v: k for k, v in SIM_DEST_OF.items()}.get(field, SIM_DEST_OF.get(field, field)).replace("_", "-")


def check_online_config(config) -> None:
    """Numbers of an OnlineConfig: finite, and none negative (every count, rate and distance)."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if not math.isfinite(value):
            raise UserError(f"{_flag_name(f.name)} (config field {f.name}) must be finite, got {value!r}")
        if value < 0:
            raise UserError(f"{_flag_name(f.name)} (config field {f.name}) must not be negative, got {value!r}")
    for name in ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate"):
        if getattr(config, name, 0) > 1:
            raise UserError(f"config field {name} is a probability (0..1), got {getattr(config, name)!r}")
    try:
        config.ga_config()
    except ValueError as exc:
        raise UserError(f"config: {exc}") from None


def online_config(args, extras: dict):
    """The OnlineConfig of parsed options and of the config file's keys without an option."""
    from cosim.online.run import OnlineConfig

    _, config_from_args = _online_cli()
    for name in ("targets", "continue_past_64", "population", "max_leg_steps", "loop_window",
                 "max_interactions", "generations_per_phase"):
        value = getattr(args, name, None)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0:
            raise UserError(f"--{name.replace('_', '-')} must not be negative, got {value!r}")
    try:
        config = config_from_args(args)
        if extras:
            config = dataclasses.replace(config, **extras)
    except (ValueError, TypeError) as exc:
        raise UserError(f"config: {exc}") from None
    if not isinstance(config, OnlineConfig):  # pragma: no cover - the contract of config_from_args
        raise TypeError(f"config_from_args gave {config!r}")
    check_online_config(config)
    from sim_world.arena import load_arena

    load_arena(config.arena)  # an ArenaError names the file and the item
    return config


def _stored_online_config(folder: Path, wanted):
    """On resume: the config stored in the checkpoint (checked), refusing options that differ."""
    from base.checkpoint import CheckpointError, read_checkpoint
    from cosim.online.run import CHECKPOINT_KIND, OnlineConfig

    stored, _ = read_checkpoint(folder / "checkpoint.json", CHECKPOINT_KIND)
    try:
        config = OnlineConfig(**stored)
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"checkpoint {str(folder / 'checkpoint.json')!r} holds a config this "
                              f"code cannot use: {exc}") from None
    default = OnlineConfig()
    differ = [f.name for f in dataclasses.fields(OnlineConfig)
              if getattr(wanted, f.name) != getattr(default, f.name)
              and getattr(wanted, f.name) != getattr(config, f.name)]
    if differ:
        raise UserError(
            f"--resume continues the run in {str(folder)!r} under its stored config; these options "
            "differ from it: " + ", ".join(f"{_flag_name(k)} {getattr(wanted, k)!r} (stored "
                                          f"{getattr(config, k)!r})" for k in differ))
    return config


def _record_session(folder: Path, backend: str, settings: dict, resumed: bool) -> list[dict]:
    """``sessions.json``: each session of the run, with its backend and HDL settings (a resumed
    run may change backend: every backend's results equal the reference's, checked per call)."""
    path = folder / "sessions.json"
    sessions = []
    if resumed and path.is_file():
        try:
            sessions = list(json.loads(path.read_text()))
        except (ValueError, TypeError):
            sessions = []
    sessions.append({"started": _dt.datetime.now().isoformat(timespec="seconds"), "backend": backend,
                     "resumed": resumed, **settings,
                     "command": " ".join([PROG, *sys.argv[1:]])[:500]})
    atomic_write_json(path, sessions)
    return sessions


def cmd_sim(args, extras: dict, sub=None) -> int:
    settings = resolve_hdl_settings(args)
    config = online_config(args, extras)
    check_learning_backend(config, args.backend)
    progress = not (args.quiet or getattr(args, "no_progress", False))
    plots = not getattr(args, "no_plots", False)
    with open_run(args.out, RESULTS / "model_based", config.seed, resume=args.resume,
                  force=args.force) as run_dir, hdl_environment(settings):
        out = run_dir.path
        if args.resume:
            config = _stored_online_config(out, config)
        sessions = _record_session(out, args.backend, settings, args.resume)
        if len({s["backend"] for s in sessions}) > 1:
            print(f"note: this run's sessions ran on {', '.join(s['backend'] for s in sessions)} "
                  "(equivalent: every board is checked against the reference)")
        write_config(out, {"backend": args.backend, **settings}, config.to_dict(), "sim")
        write_results, summary_table = _online_reporting()
        if args.backend == "cocotb":
            run_online_cocotb = _cocotb_launcher()
            print(f"cocotb backend on {settings['simulator']}")
            summary = run_online_cocotb(config, out, resume=args.resume, plots=plots, progress=progress,
                                        waves=settings["waves"], clock_hz=settings["clock_hz"],
                                        sample=settings["hdl_sample"], simulator=settings["simulator"])
        elif args.backend == "uart":  # the loop runs inside the simulation of the link top
            from cosim.launch.uart_sim import run_online_uart

            summary = run_online_uart(config, out, resume=args.resume, plots=plots, progress=progress)
        else:
            from cosim.online.run import make_run

            run = make_run(config, args.backend, out, resume=args.resume, progress=progress)
            run.run()
            summary = write_results(run, out, plots=plots)
            if args.backend in ("serial", "emulated"):
                from cosim.link.boards import write_link_summary

                write_link_summary(run, out)
        run_dir.remove_stale()
        print(summary_table(summary))
        if args.backend in LINK_BACKENDS:  # link.json: what crossed the link
            from cosim.link.boards import fault_summary, link_lines

            link = json.loads((out / "link.json").read_text())
            print("\n".join(link_lines(link)))
            if fault_summary(link) is not None:  # the summary counts the line's faults too
                atomic_write_json(out / "summary.json", {**summary, "line_faults": fault_summary(link)})
        figures = sorted(out.glob("*.png"))
        print(f"wrote {out / 'summary.json'}" + (f" and {len(figures)} figures" if figures else ""))
        report_at_end(args, out, plots)
    return 0


# -- offline --------------------------------------------------------------------------------------


def offline_parser(p) -> None:
    from cosim.offline import run as offline

    offline.add_arguments(p)
    add_common(p, out_help="the run folder (default: a fresh results/model_free/<date>-<time>-seed<S>/, "
                            "with results/model_free/latest pointing at it)")
    add_report_flag(p)


def cmd_offline(args, extras: dict, sub=None) -> int:
    from cosim.offline import run as offline

    if args.table:
        return print_table(args.table)
    for name, least in (("generations_cap", 1), ("workers", 1), ("max_leg_steps", 1), ("seed", 0),
                        ("noisy_trials", 0), ("noisy_accept_runs", 1), ("noisy_max_failures", 1),
                        ("noisy_max_generations", 1), ("noisy_race", 0), ("noisy_budget", 0),
                        ("noisy_leg_soft_steps", 0), ("noisy_final_race", 0), ("noisy_near_miss_mm", 0),
                        ("noisy_near_miss_cost", 0), ("noisy_back_cost", 0), ("noisy_final_candidates", 1),
                        ("transfer_trials", 0), ("transfer_leg_steps", 0)):
        if getattr(args, name) < least:
            raise UserError(f"--{name.replace('_', '-')} must be at least {least}, got {getattr(args, name)!r}")
    from sim_world.arena import load_arena

    load_arena(args.arena)
    with open_run(args.out, RESULTS / "model_free", args.seed, resume=args.resume, force=args.force) as run_dir:
        out = run_dir.path
        if args.resume:  # the checkpoint's config checked before anything is written
            from base.checkpoint import load_checkpoint

            load_checkpoint(out / "checkpoint.json", offline.KIND,
                            offline.run_config(args.seed, args.arena, args.max_leg_steps, offline.N_TARGETS,
                                               offline.default_ga_config(), noisy_stage(args)))
        options = {k: getattr(args, k) for k in option_keys(sub, exclude=("table",))}
        write_config(out, {k: (str(v) if isinstance(v, Path) else v) for k, v in options.items()}, {}, "offline")
        run_offline_from_args(args, out)
        run_dir.remove_stale()
        report_at_end(args, out, not args.no_plots)
    return 0


def print_table(paths) -> int:
    """``ehw offline --table SUMMARY...``: the Markdown table of off-line runs."""
    from cosim.offline.run import seeds_table

    summaries = []
    for path in paths:
        try:
            summaries.append(json.loads(Path(path).read_text()))
        except (OSError, ValueError) as exc:
            raise UserError(f"--table: cannot read the summary {str(path)!r}: {exc}") from None
    try:
        print(seeds_table(summaries), end="")
    except (KeyError, TypeError) as exc:
        raise UserError(f"--table: a file is not an off-line summary (no {exc})") from None
    return 0


def noisy_stage(args):
    """The off-line run's noisy stage from parsed ``args`` (``--noisy-*``)."""
    from cosim.offline.noisy import stage_from_args

    return stage_from_args(args)


def run_offline_from_args(args, out: Path) -> dict:
    """Run the off-line experiment of parsed ``args`` into the run folder ``out``; print the figures."""
    from cosim.offline import run as offline

    summary = offline.run_offline(
        args.seed, generations_cap=args.generations_cap, workers=args.workers, resume=args.resume,
        out=out, arena=args.arena, max_leg_steps=args.max_leg_steps, progress=not args.quiet,
        plots=not args.no_plots, noisy=noisy_stage(args), transfer_trials=args.transfer_trials,
        transfer_leg_steps=args.transfer_leg_steps,
    )
    offline._WORLDS.clear()  # free the pymunk spaces now, not during interpreter shutdown
    keys = ("seed", "reached_all_targets", "targets_reached", "generations", "genetic_operations",
            "interactions", "world_states", "transitions", "wall_time_s")
    for k in keys:
        print(f"{k:22s} {summary[k]}")
    if summary.get("transfer"):
        t = summary["transfer"]
        print(f"{'transfer (noisy world)':22s} targets before a crash: {t['targets_without_crash']}")
        print(f"{'transfer fraction':22s} {t['all_targets_fraction']} of {len(t['targets_without_crash'])} "
              f"reach every target without a crash or a time-out (leg limit {t['max_leg_steps']})")
    if summary.get("noisy_stage"):
        n = summary["noisy_stage"]
        print(f"{'noisy stage':22s} from generation {n['from_generation']}, {n['interactions']} interactions, "
              f"accepted: {n['accepted']}")
    print(f"wrote {Path(out) / 'summary.json'}")
    return summary
