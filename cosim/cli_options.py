"""What the ``ehw`` subcommands share (``cosim.cli``): the flags every run has, spelled the same
everywhere; help that shows each default; run options from a config file; the HDL settings that
were environment variables (option > environment > default, each checked before any work)."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
from pathlib import Path

from cosim.config_file import load_config_file, to_toml
from cosim.errors import UserError
from cosim.runs import atomic_write_text

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
    if clock is None:  # None: the measured Fmax of results/fpga.json, else the named default
        clock = _from_env("EHW_CLOCK_HZ", _positive_hz, "not a positive frequency in Hz")
    p_max = _from_env("EHW_SYSTEM_P_MAX", _count, "a population RAM depth")
    if p_max == 0:
        raise UserError("environment variable EHW_SYSTEM_P_MAX=0: a population RAM depth must be positive")
    return {"simulator": simulator, "hdl_sample": sample, "waves": waves,
            "clock_hz": None if clock is None else float(clock), **_link_settings(args)}


LINK_BACKENDS = ("serial", "uart")  # the backends behind the UART host link (docs/host_link.md)


def _link_settings(args) -> dict:
    """``port``, ``port2`` (``--backend serial``) and ``baud`` (serial, uart): option >
    ``EHW_PORT`` / ``EHW_PORT2`` / ``EHW_BAUD`` > None, checked against the backend and ``--ga``."""
    backend, hardware = args.backend, getattr(args, "ga", "host") == "hardware"
    for name, backends in (("port", ("serial",)), ("port2", ("serial",)), ("baud", LINK_BACKENDS)):
        if getattr(args, name, None) is not None and backend not in backends:
            raise UserError(f"--{name} is for --backend {' or '.join(backends)}, not {backend}")
    port = getattr(args, "port", None) or _from_env("EHW_PORT", str, "")
    port2 = getattr(args, "port2", None) or _from_env("EHW_PORT2", str, "")
    baud = getattr(args, "baud", None)
    if baud is not None and not (math.isfinite(baud) and baud > 0):
        raise UserError(f"--baud must be a positive baud rate, got {baud!r}")
    if baud is None:
        baud = _from_env("EHW_BAUD", _positive_hz, "not a positive baud rate")
    if backend == "serial":
        board = "one ulx3s-learner board" if hardware else "a ULX3S (ulx3s-system) or, with --port2, two iCEBreakers"
        if not port:
            raise UserError(f"the serial backend needs a port: --port /dev/ttyUSB1 for {board} "
                            "(make sim BACKEND=serial PORT=...; or EHW_PORT=...)")
        if hardware and port2:
            raise UserError(f"--ga hardware on --backend serial is one ulx3s-learner board on --port; "
                            f"--port2 {port2!r} (EHW_PORT2) is the host GA's second iCEBreaker")
    return {"port": port if backend == "serial" else None, "port2": port2 if backend == "serial" else None,
            "baud": None if baud is None or backend not in LINK_BACKENDS else float(baud)}


@contextlib.contextmanager
def hdl_environment(settings: dict):
    """The resolved settings in the process environment while a command runs (the backends read
    them there, and the cocotb simulator process inherits them); the old values come back after."""
    values = {"EHW_SIM": settings["simulator"], "EHW_HDL_SAMPLE": str(settings["hdl_sample"]),
              "WAVES": "1" if settings["waves"] else "0"}
    if settings["clock_hz"] is not None:  # else cosim.hardware_time.measured_clock decides
        values["EHW_CLOCK_HZ"] = repr(settings["clock_hz"])
    for key, name in (("port", "EHW_PORT"), ("port2", "EHW_PORT2"), ("baud", "EHW_BAUD")):
        if settings.get(key) is not None:  # the link backends read them there (cosim.link_boards)
            values[name] = settings[key] if key != "baud" else repr(settings[key])
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
    p.add_argument("--port", default=None, metavar="PORT",
                   help="--backend serial: the board's serial port, a device or a pyserial URL: a ULX3S "
                        "with ulx3s-system, or with --ga hardware ulx3s-learner (default: $EHW_PORT)")
    p.add_argument("--port2", default=None, metavar="PORT",
                   help="--backend serial with the host GA: the evaluator iCEBreaker's port; --port is "
                        "then the controller's (default: $EHW_PORT2)")
    p.add_argument("--baud", type=float, default=None, metavar="BAUD",
                   help="--backend serial or uart: the link's baud (default: $EHW_BAUD, else 115200 on "
                        "serial and the simulated clock / 4 on uart)")
    p.add_argument("--clock-hz", type=float, default=None, metavar="HZ",
                   help="FPGA clock of the hardware-time figures (default: $EHW_CLOCK_HZ, else the "
                        "measured Fmax in results/fpga.json, else 12e6, the iCEBreaker's)")


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
    if isinstance(action, argparse._AppendAction):  # a repeatable option: a list in the file
        return list[action.type if action.type in (int, float) else str]
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


def resume_config(args, root: Path) -> Path | None:
    """With ``--resume`` and no ``--config``: the ``config.toml`` of the run being resumed (the
    ``--out`` folder, else the one ``root/latest`` points at), whose options become the defaults
    (flags over them); None where there is none."""
    from cosim.runs import read_latest

    if not getattr(args, "resume", False) or getattr(args, "config", None) is not None:
        return None
    folder = args.out if args.out is not None else read_latest(root)
    path = None if folder is None else Path(folder) / "config.toml"
    return path if path is not None and path.is_file() else None


def write_config(folder: Path, run_options: dict, config: dict, what: str) -> Path:
    header = (f"The complete config of this {what} run, as --config reads it back:\n"
              f"  {PROG} {what} --config {folder / 'config.toml'} --out NEW_FOLDER")
    return atomic_write_text(folder / "config.toml", to_toml({**run_options, **config}, header))
