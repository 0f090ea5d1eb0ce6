"""``ehw``: the project's one command line (a console script, ``pyproject.toml``).

    ehw sim       [--backend reference|amaranth|cocotb] [--seed 1] [--out DIR] [--resume] ...
    ehw offline   [--seed 1] [--generations-cap G] [--workers W] [--out DIR] [--resume] ...
    ehw compare   [--seeds 5] [--jobs 2] [--out results] ...   (cosim.compare's own options)
    ehw verilog   [--out build/verilog] [BLOCK ...]
    ehw bitstream ...                                        (hdl.fpga, where the checkout has it)
    ehw bench     [MODULE ...] [--out results/bench.json]
    ehw arena     [--arena NAME|FILE ...] [--out results]
    ehw baseline  [--arena default] [--seeds 5] [--out results]

One parser module: each subcommand takes its module's own argument definitions (``add_arguments``
of ``cosim.offline``, ``sim_world.render``, ...; for ``sim`` those of the on-line experiment),
plus the flags every run shares, spelled the same everywhere: ``--seed``, ``--out``, ``--resume``,
``--force``, ``--quiet``, ``--config``. ``--help`` shows every option's default.

- **Where results go** (``cosim.runs``): without ``--out`` each run of ``sim`` / ``offline`` gets a
  fresh folder ``results/<method>/<date>-<time>-seed<S>/`` and ``results/<method>/latest`` points
  at it; an ``--out`` that holds a run is refused unless ``--resume`` or ``--force``; a folder in
  use by another run is refused (a lock); every result file is written atomically.
- **Config files** (``cosim.config_file``): ``--config run.toml`` sets any run option; flags
  override it. Each run writes ``config.toml`` beside its summary, which ``--config`` takes back
  (as it takes the ``summary.json``), so a run is re-run from its results.
- **Settings that were environment variables** are options now; the variables remain a fallback
  (option > environment > default): ``--simulator`` (``EHW_SIM``, default verilator, as ``make
  sim``), ``--hdl-sample`` (``EHW_HDL_SAMPLE``), ``--waves`` (``WAVES``), ``--clock-hz``
  (``EHW_CLOCK_HZ``). All are checked before any work.
- **Errors** (``cosim.errors``): a user error is one ``error: ...`` line on stderr and exit
  status 2; a traceback means a bug.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime as _dt
import importlib
import importlib.util
import json
import math
import os
import sys
from pathlib import Path
from typing import Sequence

from cosim.config_file import ConfigFileError, check_value, field_types, load_config_file, to_toml
from cosim.errors import ArgumentParser, UserError, run_main
from cosim.runs import RunLock, atomic_write_json, atomic_write_text, open_run

PROG = "ehw"
RESULTS = Path("results")
# Options that only say how a command runs, never what it computes: not recorded in config.toml.
NOT_CONFIG = {"out", "resume", "force", "config", "quiet", "no_progress", "command", "help"}


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Every option's default after its help (unless the help already says it)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "%(default)" in text or "(default" in text or action.default in (None, argparse.SUPPRESS, False) \
                or not action.option_strings or isinstance(action.default, list) and not action.default:
            return text
        return f"{text} (default: %(default)s)".lstrip()


# -- settings from options, the environment as a fallback -------------------------------------------


def _from_env(name: str, parse, what: str):
    """``parse(os.environ[name])``, None when unset or empty; a bad value is a UserError."""
    raw = os.environ.get(name, "")
    if raw == "":
        return None
    try:
        return parse(raw)
    except (ValueError, TypeError):
        raise UserError(f"environment variable {name}={raw!r}: {what}") from None


def _positive_hz(text) -> float:
    hz = float(text)
    if not (math.isfinite(hz) and hz > 0):
        raise ValueError(hz)
    return hz


def _count(text) -> int:
    value = int(str(text), 10)
    if value < 0:
        raise ValueError(value)
    return value


def _flag(text) -> bool:
    value = str(text).strip().lower()
    if value in ("1", "true", "yes", "on"):
        return True
    if value in ("", "0", "false", "no", "off"):
        return False
    raise ValueError(value)


def resolve_hdl_settings(args) -> dict:
    """The HDL settings of a run, option > environment > default, each checked: ``simulator``,
    ``hdl_sample``, ``waves``, ``clock_hz`` (see :func:`hdl_environment`)."""
    from cosim.cocotb_run import SIMULATORS
    from cosim.hardware_time import CLOCK_HZ

    simulator = getattr(args, "simulator", None) or _from_env("EHW_SIM", str, "") or "verilator"
    if simulator not in SIMULATORS:
        source = "--simulator" if getattr(args, "simulator", None) else "environment variable EHW_SIM"
        raise UserError(f"{source}: {simulator!r} is not a simulator; choose one of {', '.join(SIMULATORS)}")
    sample = getattr(args, "hdl_sample", None)
    if sample is None:
        sample = _from_env("EHW_HDL_SAMPLE", _count, "a count of controllers (0: all)")
    if sample is None:  # all of them on cocotb+Verilator, a spot check of 1 where all take hours
        sample = 0 if (args.backend == "cocotb" and simulator == "verilator") else 1
    if sample < 0:
        raise UserError(f"--hdl-sample must be a count of controllers (0: all), got {sample!r}")
    waves = getattr(args, "waves", None)
    if waves is None:
        waves = bool(_from_env("WAVES", _flag, "0 or 1"))
    clock = getattr(args, "clock_hz", None)
    if clock is not None and not (math.isfinite(clock) and clock > 0):
        raise UserError(f"--clock-hz must be a positive frequency in Hz, got {clock!r}")
    if clock is None:
        clock = _from_env("EHW_CLOCK_HZ", _positive_hz, "not a positive frequency in Hz") or CLOCK_HZ
    p_max = _from_env("EHW_SYSTEM_P_MAX", _count, "a population RAM depth")
    if p_max == 0:
        raise UserError("environment variable EHW_SYSTEM_P_MAX=0: a population RAM depth must be positive")
    return {"simulator": simulator, "hdl_sample": sample, "waves": waves, "clock_hz": float(clock)}


@contextlib.contextmanager
def hdl_environment(settings: dict):
    """The resolved settings in the process environment while a command runs (the backends read
    them there, and the cocotb simulator process inherits them); the old values come back after."""
    values = {"EHW_SIM": settings["simulator"], "EHW_HDL_SAMPLE": str(settings["hdl_sample"]),
              "WAVES": "1" if settings["waves"] else "0", "EHW_CLOCK_HZ": repr(settings["clock_hz"])}
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _add_hdl_options(p) -> None:
    p.add_argument("--simulator", choices=("icarus", "verilator"), default=None,
                   help="the Verilog simulator of --backend cocotb (default: $EHW_SIM, else "
                        "verilator: a 64-target run in minutes; icarus is ~50x slower)")
    p.add_argument("--hdl-sample", type=int, default=None, metavar="K",
                   help="HDL backends: controllers per population the HDL evaluates, each checked "
                        "against the reference (0: all; default: $EHW_HDL_SAMPLE, else 0 on "
                        "cocotb+verilator and 1 elsewhere)")
    p.add_argument("--waves", action=argparse.BooleanOptionalAction, default=None,
                   help="dump the HDL simulation's waveforms (default: $WAVES, else off)")
    p.add_argument("--clock-hz", type=float, default=None, metavar="HZ",
                   help="FPGA clock of the hardware-time figures (default: $EHW_CLOCK_HZ, else 12e6, "
                        "the iCEBreaker's)")


def _add_common(p, *, seed: bool = True, out_help: str = "", resume: bool = True,
                force: bool = True, quiet: bool = True, config: bool = True) -> None:
    """The flags every run shares, spelled the same in every subcommand."""
    if seed:
        p.add_argument("--seed", type=int, default=1, help="the run's seed")
    if out_help:
        p.add_argument("--out", type=Path, default=None, metavar="DIR", help=out_help)
    if resume:
        p.add_argument("--resume", action="store_true",
                       help="continue the run in --out (without --out: the one 'latest' points at) "
                            "from its checkpoint, under the config stored there")
    if force:
        p.add_argument("--force", action="store_true",
                       help="replace the run --out holds (its result files are deleted first)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress bar")
    if config:
        p.add_argument("--config", type=Path, default=None, metavar="FILE",
                       help="run options from a TOML file (or a run's config.toml / summary.json); "
                            "flags override it")


def _fill_help(p, note: str) -> None:
    """Options without a help text get one (``--help`` then lists every option and its default)."""
    for action in p._actions:
        if action.help is None and action.option_strings:
            action.help = note.format(dest=action.dest)


# -- config files ---------------------------------------------------------------------------------


def _action_type(action):
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse.BooleanOptionalAction)):
        return bool
    if action.type in (int, float, str):
        return action.type | None if action.default is None else action.type
    if action.type is Path or action.type is None:
        return str | None if action.default is None else str
    return str


def _option_keys(parser, exclude=()) -> dict[str, argparse.Action]:
    return {a.dest: a for a in parser._actions
            if a.option_strings and a.dest not in NOT_CONFIG and a.dest not in exclude
            and not isinstance(a, argparse._HelpAction)}


def apply_config_file(sub, path, extra_types: dict | None = None, dest_of: dict | None = None) -> dict:
    """Set ``sub``'s defaults from the config file ``path``; return the keys that have no option
    (``extra_types`` lists those allowed; ``dest_of`` maps a key to its option's dest)."""
    actions = _option_keys(sub)
    dest_of = dest_of or {}
    key_of = {dest: key for key, dest in dest_of.items()}
    types_of = {key_of.get(dest, dest): _action_type(action) for dest, action in actions.items()}
    types_of.update(extra_types or {})  # a config dataclass's own field types come first
    choices = {key: tuple(actions[dest_of.get(key, key)].choices) for key in types_of
               if dest_of.get(key, key) in actions and actions[dest_of.get(key, key)].choices}
    values = load_config_file(path, types_of, choices)
    defaults, extras = {}, {}
    for key, value in values.items():
        dest = dest_of.get(key, key)
        if dest in actions:
            defaults[dest] = str(value) if actions[dest].type is Path and value is not None else value
        else:
            extras[key] = value
    sub.set_defaults(**defaults)
    return extras


# -- sim: the on-line experiment ------------------------------------------------------------------

# The on-line command line lives with the experiment: cosim.online_cli (add_arguments,
# config_from_args) where the checkout has it, else cosim.online's build_parser.


def _online_cli():
    try:
        module = importlib.import_module("cosim.online_cli")
    except ModuleNotFoundError as exc:
        if exc.name != "cosim.online_cli":
            raise
        from cosim import online

        def add_arguments(p):
            p._add_container_actions(online.build_parser())
            return p

        return add_arguments, online.config_from_args
    return module.add_arguments, module.config_from_args


def _online_reporting():
    try:
        report = importlib.import_module("cosim.online_report")
    except ModuleNotFoundError as exc:
        if exc.name != "cosim.online_report":
            raise
        from cosim import online as report
    return report.write_results, report.summary_table


SIM_DEST_OF = {"n_targets": "targets", "distance_rule": "distance"}
SIM_RUN_OPTIONS = {"backend": str, "simulator": str | None, "hdl_sample": int | None,
                   "waves": bool | None, "clock_hz": float | None}


def _sim_parser(p) -> None:
    add_arguments, _ = _online_cli()
    add_arguments(p)
    _fill_help(p, "the run config's {dest} (cosim.online.OnlineConfig)")
    for action in p._actions:  # the options are checked once more on the config they make
        if action.dest == "no_plots":
            action.help = "write no figures (an earlier run's figures are removed all the same)"
        if action.dest == "no_progress":
            action.help = "no progress bar (as --quiet)"
        if action.dest == "backend":
            action.help = ("the boards: the NumPy reference, Amaranth's simulator, or cocotb on the "
                           "Verilog (see --simulator, --hdl-sample)")
    _add_common(p, out_help="the run folder (default: a fresh results/model_based/<date>-<time>-seed<S>/, "
                            "with results/model_based/latest pointing at it)")
    _add_hdl_options(p)


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
    from cosim.online import OnlineConfig

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
    from cosim.checkpoint import CheckpointError, read_checkpoint
    from cosim.online import CHECKPOINT_KIND, OnlineConfig

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


def _write_config(folder: Path, run_options: dict, config: dict, what: str) -> Path:
    header = (f"The complete config of this {what} run, as --config reads it back:\n"
              f"  {PROG} {what} --config {folder / 'config.toml'} --out NEW_FOLDER")
    return atomic_write_text(folder / "config.toml", to_toml({**run_options, **config}, header))


def cmd_sim(args, extras: dict) -> int:
    settings = resolve_hdl_settings(args)
    config = online_config(args, extras)
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
        _write_config(out, {"backend": args.backend, **settings}, config.to_dict(), "sim")
        write_results, summary_table = _online_reporting()
        if args.backend == "cocotb":
            from cosim.cocotb_backend import run_online_cocotb

            print(f"cocotb backend on {settings['simulator']}")
            summary = run_online_cocotb(config, out, resume=args.resume, plots=plots, progress=progress,
                                        waves=settings["waves"], clock_hz=settings["clock_hz"],
                                        sample=settings["hdl_sample"], simulator=settings["simulator"])
        else:
            from cosim.online import make_run

            run = make_run(config, args.backend, out, resume=args.resume, progress=progress)
            run.run()
            summary = write_results(run, out, plots=plots)
        run_dir.remove_stale()
        print(summary_table(summary))
        print(f"wrote {out / 'summary.json'}" + (f" and {len(summary.get('plots', []))} plots" if plots else ""))
    return 0


# -- offline --------------------------------------------------------------------------------------


def _offline_parser(p) -> None:
    from cosim import offline

    offline.add_arguments(p)
    _add_common(p, out_help="the run folder (default: a fresh results/model_free/<date>-<time>-seed<S>/, "
                            "with results/model_free/latest pointing at it)")


def cmd_offline(args, extras: dict) -> int:
    from cosim import offline

    if args.table:
        return offline.print_table(args.table)
    for name in ("generations_cap", "workers", "max_leg_steps"):
        if getattr(args, name) < 1:
            raise UserError(f"--{name.replace('_', '-')} must be at least 1, got {getattr(args, name)!r}")
    from sim_world.arena import load_arena

    load_arena(args.arena)
    with open_run(args.out, RESULTS / "model_free", args.seed, resume=args.resume, force=args.force) as run_dir:
        out = run_dir.path
        if args.resume:  # the checkpoint's config checked before anything is written
            from cosim.checkpoint import load_checkpoint

            load_checkpoint(out / "checkpoint.json", offline.KIND,
                            offline.run_config(args.seed, args.arena, args.max_leg_steps, offline.N_TARGETS,
                                               offline.default_ga_config()))
        options = {k: getattr(args, k) for k in _option_keys(_SUBPARSERS["offline"], exclude=("table",))}
        _write_config(out, {k: (str(v) if isinstance(v, Path) else v) for k, v in options.items()}, {}, "offline")
        offline.run_from_args(args, out)
        run_dir.remove_stale()
    return 0


# -- the other subcommands ------------------------------------------------------------------------


def _lock_out(folder: Path):
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"--out {str(folder)!r} is a file, not a folder")
    folder.mkdir(parents=True, exist_ok=True)
    return RunLock(folder)


def _compare_parser(p) -> None:
    p.add_argument("compare_args", nargs=argparse.REMAINDER, metavar="...",
                   help="cosim.compare's options: see 'ehw compare --help'")


def check_compare_inputs(argv: Sequence[str]) -> Path:
    """What ``cosim.compare`` reads, checked before it runs anything: its --out folder, and with
    --adaptation-only the compare.json it extends."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--out", type=Path, default=Path("results"))
    pre.add_argument("--adaptation-only", action="store_true")
    pre.add_argument("--blind-bit", type=int, default=None)
    pre.add_argument("--blind-after-target", type=int, default=None)
    pre.add_argument("--seeds", type=int, default=5)
    pre.add_argument("--jobs", type=int, default=2)
    known, _ = pre.parse_known_args(list(argv))
    if known.seeds < 1 or known.jobs < 1:
        raise UserError(f"--seeds and --jobs must be at least 1, got {known.seeds!r} and {known.jobs!r}")
    if (known.blind_bit is None) != (known.blind_after_target is None):
        raise UserError("--blind-bit and --blind-after-target go together")
    if known.blind_bit is not None and known.blind_bit not in range(6):
        raise UserError(f"--blind-bit must be an IR bit 0..5, got {known.blind_bit!r}")
    if known.adaptation_only:
        if known.blind_bit is None:
            raise UserError("--adaptation-only needs --blind-bit B and --blind-after-target T")
        path = known.out / "compare.json"
        try:
            report = json.loads(path.read_text())
        except OSError as exc:
            raise UserError(f"--adaptation-only extends {str(path)!r}, which cannot be read "
                            f"({exc.strerror}): run 'ehw compare' first") from None
        except ValueError as exc:
            raise UserError(f"--adaptation-only: {str(path)!r} is not valid JSON ({exc})") from None
        if not isinstance(report, dict) or not isinstance(report.get("per_seed"), dict):
            raise UserError(f"--adaptation-only: {str(path)!r} is not a compare report (no per_seed)")
    return known.out


def cmd_compare(args, extras: dict) -> int:
    from cosim import compare

    argv = list(args.passed)
    if any(a in ("-h", "--help") for a in argv):
        return compare.main(argv) or 0
    out = check_compare_inputs(argv)
    with _lock_out(out):
        try:
            return compare.main(argv) or 0
        except SystemExit as exc:  # its own messages for bad options: the one-line form here
            if isinstance(exc.code, str):
                raise UserError(exc.code) from None
            raise


def _verilog_parser(p) -> None:
    from hdl import generate

    generate.add_arguments(p)


def cmd_verilog(args, extras: dict) -> int:
    from hdl import generate

    return generate.run_from_args(args) or 0


def _bench_parser(p) -> None:
    import benchmarks.__main__ as bench

    bench.add_arguments(p)
    _add_common(p, seed=False, resume=False, force=False, quiet=False, config=False)


def cmd_bench(args, extras: dict) -> int:
    import benchmarks.__main__ as bench

    resolve_hdl_settings(argparse.Namespace(backend="cocotb"))  # the environment's values checked first
    with _lock_out(Path(args.out).parent):
        return bench.run_from_args(args) or 0


def _arena_parser(p) -> None:
    from sim_world import render

    render.add_arguments(p)


def cmd_arena(args, extras: dict) -> int:
    from sim_world import render
    from sim_world.arena import ARENAS, load_arena

    for name in args.arena or ARENAS:  # every file checked before anything is written
        load_arena(name)
    with _lock_out(args.out):
        return render.run_from_args(args) or 0


def _baseline_parser(p) -> None:
    from sim_world import baseline

    baseline.add_arguments(p)
    _add_common(p, seed=False, resume=False, force=False, quiet=False)


def cmd_baseline(args, extras: dict) -> int:
    from sim_world import baseline

    if args.seeds < 0 or args.max_leg_steps < 1 or not (math.isfinite(args.tune) and args.tune >= 0):
        raise UserError("--seeds must be >= 0, --max-leg-steps >= 1 and --tune a finite number of "
                        f"seconds >= 0; got {args.seeds!r}, {args.max_leg_steps!r}, {args.tune!r}")
    from sim_world.arena import load_arena

    load_arena(args.arena)
    with _lock_out(args.out):
        return baseline.run_from_args(args) or 0


# Subcommands whose module comes from other work: listed only where the checkout has the module
# (``formal`` joins here once its module is on main: one line).
EXTERNAL = {"bitstream": ("hdl.fpga", "FPGA bitstreams of the EHW boards (hdl.fpga)")}


def _external_parser(p) -> None:
    p.add_argument("module_args", nargs=argparse.REMAINDER, metavar="...",
                   help="the module's own options: see 'ehw <command> --help'")


def _cmd_external(module_name: str):
    def run(args, extras: dict) -> int:
        module = importlib.import_module(module_name)
        return module.main(list(args.passed)) or 0
    return run


PASS_THROUGH = ("compare", *EXTERNAL)
COMMANDS = {
    "sim": (_sim_parser, cmd_sim, "the on-line model-based experiment: one robot lifetime (paper 5.2)"),
    "offline": (_offline_parser, cmd_offline, "the off-line model-free experiment (paper 5.1)"),
    "compare": (_compare_parser, cmd_compare, "both methods and the baseline over N seeds -> compare.md"),
    "verilog": (_verilog_parser, cmd_verilog, "the Verilog of the EHW blocks -> build/verilog/"),
    "bench": (_bench_parser, cmd_bench, "speed figures -> results/bench.json"),
    "arena": (_arena_parser, cmd_arena, "render arenas -> results/arena_<name>.png"),
    "baseline": (_baseline_parser, cmd_baseline, "the hand-written reactive baseline through the 64 legs"),
}
_SUBPARSERS: dict[str, argparse.ArgumentParser] = {}


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(prog=PROG, description="The evolvable-hardware robot (Keymeulen et al. 1998): experiments, Verilog, benchmarks.",
                            formatter_class=HelpFormatter,
                            epilog="Each command's options: ehw COMMAND --help. Results: results/ "
                                   "(README: 'Running it').")
    subs = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgumentParser)
    commands = dict(COMMANDS)
    for name, (module, text) in EXTERNAL.items():
        if importlib.util.find_spec(module) is not None:
            commands[name] = (_external_parser, _cmd_external(module), text)
    for name, (add, _, text) in commands.items():
        sub = subs.add_parser(name, help=text, description=text, formatter_class=HelpFormatter,
                              conflict_handler="resolve")
        add(sub)
        _SUBPARSERS[name] = sub
    parser.set_defaults(_commands=commands)
    return parser


def _main(argv: Sequence[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    commands = parser.get_default("_commands")
    if argv and argv[0] in PASS_THROUGH and argv[0] in commands:
        # The module parses its own options (argparse cannot hand on "--x ..." as a remainder).
        return commands[argv[0]][1](argparse.Namespace(passed=argv[1:]), {})
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    extras = {}
    if args.command == "offline" and args.resume and args.config is None:
        # A resumed run keeps its options: the run folder's config.toml, flags over it (the
        # checkpoint then refuses a flag that changes the run, naming the key).
        from cosim.runs import read_latest

        folder = args.out if args.out is not None else read_latest(RESULTS / "model_free")
        if folder is not None and (Path(folder) / "config.toml").is_file():
            args.config = Path(folder) / "config.toml"
            argv = [*argv, "--config", str(args.config)]
    if getattr(args, "config", None) is not None:
        sub = _SUBPARSERS[args.command]
        if args.command == "sim":
            from cosim.online import OnlineConfig

            extras = apply_config_file(sub, args.config, {**field_types(OnlineConfig), **SIM_RUN_OPTIONS},
                                       SIM_DEST_OF)
        else:
            extras = apply_config_file(sub, args.config)
        args = parser.parse_args(argv)  # flags override the file
    return args._commands[args.command][1](args, extras)


def main(argv: Sequence[str] | None = None) -> int:
    """``ehw ...``: the exit status (2 and one ``error:`` line for a user error)."""
    return run_main(_main, argv)


def entry() -> None:  # the console script
    raise SystemExit(main())


if __name__ == "__main__":
    entry()
