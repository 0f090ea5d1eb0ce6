"""``ehw``: the project's one command line (a console script, ``pyproject.toml``).

    ehw sim       [--backend reference|amaranth|cocotb|serial|uart|emulated] [--seed 1] [--out DIR] [--resume] ...
    ehw offline   [--seed 1] [--generations-cap G] [--workers W] [--out DIR] [--resume] ...
    ehw compare   [--seeds 5] [--first-seed 1] [--methods ...] [--jobs 2] [--out DIR] [--resume] ...
    ehw verilog   [--out build/verilog] [BLOCK ...]
    ehw bitstream ...                                        (hdl.fpga, where the checkout has it)
    ehw gatesim   [TARGET ...] [--netlist synth|pnr] [--simulator ...] (cosim.launch.gatesim)
    ehw bench     [MODULE ...] [--out DIR] [--figures results/bench.json]
    ehw arena     [--arena NAME|FILE ...] [--out DIR]
    ehw baseline  [--arena default] [--seeds 5] [--out DIR]
    ehw replay    [RUN_DIR] [--fps 15] [--max-seconds 30] [--format auto|mp4|gif]   (cosim.report)
    ehw report    [RUN_DIR] [--fps 15] [--max-seconds 30]      (report.html; also after sim/offline/compare)

One parser module: each subcommand takes its module's own argument definitions (``add_arguments``
of ``cosim.offline.run``, ``sim_world.render``, ...; for ``sim`` those of the on-line experiment),
plus the flags every run shares, spelled the same everywhere: ``--seed``, ``--out``, ``--resume``,
``--force``, ``--quiet``, ``--config``. ``--help`` shows every option's default.

- **Where results go** (``base.runs``): without ``--out`` each run gets a fresh folder
  ``results/<what>/<date>-<time>[-seed<S>|-seeds<A>-<B>]/`` and ``results/<what>/latest`` points
  at it (``<what>``: ``model_based`` for sim, ``model_free`` for offline, ``compare``,
  ``baseline``, ``arena``, ``bench``); an ``--out`` that holds a run is refused unless
  ``--resume`` or ``--force``; a folder in use by another run is refused (a lock); every result
  file is written atomically. ``compare``'s lifetime cache (``results/compare/cache``) is shared
  by every comparison; ``bench`` also merges its figures into ``results/bench.json``.
- **Config files** (``base.config_file``): ``--config run.toml`` sets any run option; flags
  override it. Each run writes ``config.toml`` beside its summary, which ``--config`` takes back
  (as it takes the ``summary.json``), so a run is re-run from its results.
- **Settings that were environment variables** are options now; the variables remain a fallback
  (option > environment > default): ``--simulator`` (``EHW_SIM``, default verilator, as ``make
  sim``), ``--hdl-sample`` (``EHW_HDL_SAMPLE``), ``--waves`` (``WAVES``), ``--clock-hz``
  (``EHW_CLOCK_HZ``). All are checked before any work.
- **Errors** (``base.errors``): a user error is one ``error: ...`` line on stderr and exit
  status 2; a traceback means a bug.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import math
import sys
from pathlib import Path
from typing import Sequence

from base import environ
from base.config_file import field_types
from base.errors import ArgumentParser, UserError, run_main
from base.options import PROG, HelpFormatter, add_common, apply_config_file, option_keys, resume_config, write_config
from base.runs import RunLock, open_run
from cosim.cli.commands import SIM_DEST_OF, SIM_RUN_OPTIONS, cmd_offline, cmd_sim, offline_parser, sim_parser
from cosim.cli.gatesim import cmd_gatesim, gatesim_parser
from cosim.cli.limit import cmd_limit, limit_parser
from cosim.cli.options import RESULTS
from cosim.cli.report import add_report_flag, cmd_replay, cmd_report, replay_parser, report_at_end, report_parser
from cosim.cli.tune import cmd_tune, tune_parser
from cosim.compare.options import COMPARE_ROOT

# -- the other subcommands ------------------------------------------------------------------------


def _lock_out(folder: Path):
    """The lock of an output folder of build files (``ehw verilog``: created, and refused when it
    is a file or not writable)."""
    from base.runs import RunFolderError

    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"--out {str(folder)!r} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        return RunLock(folder).acquire()
    except OSError as exc:
        raise RunFolderError(f"cannot write into --out {str(folder)!r}: {exc.strerror or exc}") from None


def _record_options(folder: Path, args, sub, what: str) -> None:
    """The run's options as ``config.toml`` in its folder (``--config`` takes it back)."""
    options = {k: getattr(args, k) for k in option_keys(sub)}
    write_config(folder, {k: (str(v) if isinstance(v, Path) else v) for k, v in options.items()}, {}, what)


def _in_run_folder(run, args, sub, what: str, markers: tuple, label: str | None = None) -> int:
    """``run(args)`` with ``args.out`` a run folder of ``results/<what>/`` (its options recorded,
    the files of an earlier run it replaces removed)."""
    with open_run(args.out, RESULTS / what, force=args.force, checkpoint=None, markers=markers,
                  label=label) as run_dir:
        _record_options(run_dir.path, args, sub, what)
        args.out = run_dir.path
        run(args)
        run_dir.remove_stale()
    return 0


def _compare_parser(p) -> None:
    from cosim.compare.options import add_arguments

    add_arguments(p)
    add_common(p, seed=False, resume=False, force=False, quiet=False)  # --config
    add_report_flag(p)


def cmd_compare(args, extras: dict, sub=None) -> int:
    from cosim.compare import run as compare

    status = compare.run_from_args(args)
    if status == 0 and args.render is None:  # the folder it wrote: --out, or the one 'latest' points at
        folder = Path(args.out) if args.out is not None else COMPARE_ROOT / "latest"
        with RunLock(folder).acquire():
            report_at_end(args, folder)
    return status


def _verilog_parser(p) -> None:
    from hdl import generate

    generate.add_arguments(p)


def cmd_verilog(args, extras: dict, sub=None) -> int:
    from hdl import generate

    with _lock_out(Path(args.out)):
        return generate.run_from_args(args) or 0


def _arena_parser(p) -> None:
    from sim_world import render

    render.add_arguments(p)
    add_common(p, seed=False, resume=False, quiet=False,
                out_help="the folder of the pictures (default: a fresh results/arena/<date>-<time>/, with "
                         "results/arena/latest pointing at it)")


def cmd_arena(args, extras: dict, sub=None) -> int:
    from sim_world import render
    from sim_world.arena import ARENAS, load_arena

    for name in args.arena or ARENAS:  # every file checked before anything is written
        load_arena(name)
    return _in_run_folder(render.run_from_args, args, sub, "arena", ("arena_*.png",))


def _baseline_parser(p) -> None:
    from sim_world import baseline

    baseline.add_arguments(p)
    add_common(p, seed=False, resume=False, quiet=False,
                out_help="the run folder of baseline.json and baseline_trajectory.png (default: a fresh "
                         "results/baseline/<date>-<time>-seeds<A>-<B>/, with results/baseline/latest "
                         "pointing at it)")


def cmd_baseline(args, extras: dict, sub=None) -> int:
    from sim_world import baseline

    for name, least in (("seeds", 0), ("first_seed", 0), ("max_leg_steps", 1)):
        if getattr(args, name) < least:
            raise UserError(f"--{name.replace('_', '-')} must be at least {least}, got {getattr(args, name)!r}")
    if not (math.isfinite(args.tune) and args.tune >= 0):
        raise UserError(f"--tune must be a finite number of seconds >= 0, got {args.tune!r}")
    from sim_world.arena import load_arena

    load_arena(args.arena)
    if args.tune:  # the search prints its table and writes no file
        return baseline.run_from_args(args) or 0
    label = f"seeds{args.first_seed}-{args.first_seed + args.seeds - 1}" if args.seeds else "noise-free"
    return _in_run_folder(baseline.run_from_args, args, sub, "baseline", ("baseline.json",), label)


# Subcommands whose module parses its own options (by module name: the command line imports none
# of them, and lists one only where the checkout has its module).
EXTERNAL = {"bitstream": ("hdl.fpga", "FPGA bitstreams of the EHW boards (hdl.fpga)"),
            "bench": ("benchmarks.__main__", "speed figures -> results/bench/<date>-<time>/bench.json, "
                                             "merged into results/bench.json"),
            "formal": ("formal.__main__", "the formal proofs of the gateware -> results/formal.json (docs/formal.md)")}


def _external_parser(p) -> None:
    p.add_argument("module_args", nargs=argparse.REMAINDER, metavar="...",
                   help="the module's own options: see 'ehw <command> --help'")


def _cmd_external(module_name: str):
    def run(args, extras: dict, sub=None) -> int:
        module = importlib.import_module(module_name)
        return module.main(list(args.passed)) or 0
    return run


PASS_THROUGH = tuple(EXTERNAL)
# The commands whose --resume continues a run folder under its stored config.toml.
RESUMED_ROOTS = {"offline": RESULTS / "model_free", "compare": COMPARE_ROOT}
COMMANDS = {
    "sim": (sim_parser, cmd_sim, "the on-line model-based experiment: one robot lifetime (paper 5.2)"),
    "offline": (offline_parser, cmd_offline, "the off-line model-free experiment (paper 5.1)"),
    "compare": (_compare_parser, cmd_compare, "every method (on-line, off-line, baseline, RL peers) over N seeds -> results/compare/<date>-<time>-seeds<A>-<B>/compare.md/.json/.png"),
    "verilog": (_verilog_parser, cmd_verilog, "the Verilog of the EHW blocks -> build/verilog/"),
    "arena": (_arena_parser, cmd_arena, "render arenas -> results/arena/<date>-<time>/arena_<name>.png"),
    "gatesim": (gatesim_parser, cmd_gatesim, "the bitstream targets' synthesised netlists driven by the host code over their UART pins -> results/gatesim.json"),
    "baseline": (_baseline_parser, cmd_baseline, "the hand-written reactive baseline through the 64 legs -> results/baseline/<date>-<time>-seeds<A>-<B>/"),
    "replay": (replay_parser, cmd_replay, "a lifetime as a video (the arena, the robot, its IR bits, trail, crashes, targets, phases) -> RUN_DIR/replay.mp4"),
    "report": (report_parser, cmd_report, "one self-contained report.html of a run folder (summary, replay, curves, world model, controller, config)"),
    "limit": (limit_parser, cmd_limit, "the fewest interactions any controller could need (omniscient planner) -> results/limit/<date>-<time>/"),
    "tune": (tune_parser, cmd_tune, "equal-effort tuning of one learning method (Optuna TPE) -> results/tune/<method>[-<shaping>].db/.json"),
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
        try:
            found = importlib.util.find_spec(module) is not None
        except ModuleNotFoundError:  # the parent package is absent
            found = False
        if found:
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
    environ.check_all()  # every variable the project reads, before any work (base.environ)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    extras = {}
    if args.command in RESUMED_ROOTS and not getattr(args, "adaptation_only", False):
        # A resumed run keeps its options: the run folder's config.toml, flags over it (the
        # checkpoint, or the stored config, then refuses a flag that changes the run, naming it).
        stored = resume_config(args, RESUMED_ROOTS[args.command])
        if stored is not None:
            args.config = stored
            argv = [*argv, "--config", str(stored)]
    if getattr(args, "config", None) is not None:
        sub = _SUBPARSERS[args.command]
        if args.command == "sim":
            from cosim.online.run import OnlineConfig

            extras = apply_config_file(sub, args.config, {**field_types(OnlineConfig), **SIM_RUN_OPTIONS},
                                       SIM_DEST_OF)
        else:
            extras = apply_config_file(sub, args.config)
        args = parser.parse_args(argv)  # flags override the file
    return args._commands[args.command][1](args, extras, _SUBPARSERS[args.command])


def main(argv: Sequence[str] | None = None) -> int:
    """``ehw ...``: the exit status (2 and one ``error:`` line for a user error)."""
    return run_main(_main, argv)


def entry() -> None:  # the console script
    raise SystemExit(main())


if __name__ == "__main__":
    entry()
