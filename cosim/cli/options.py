"""What the ``ehw`` subcommands of the simulators share (``cosim.cli.main``): the HDL settings
that were environment variables (option > environment > default, each checked before any work)
and their options. The flags every run has, the help formatter and config files: ``base.options``."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
from pathlib import Path

from base import environ
from base.errors import UserError

RESULTS = Path("results")


# -- settings from options, the environment as a fallback -------------------------------------------


def _from_env(name: str):
    """The typed value of variable ``name`` (``base.environ``), None when unset or empty."""
    return environ.read(name)


def resolve_hdl_settings(args) -> dict:
    """The HDL settings of a run, option > environment > default, each checked: ``simulator``,
    ``hdl_sample``, ``waves``, ``clock_hz`` (see :func:`hdl_environment`)."""
    from cosim.boards.cocotb_run import SIMULATORS

    simulator = getattr(args, "simulator", None) or _from_env("EHW_SIM") or "verilator"
    if simulator not in SIMULATORS:
        source = "--simulator" if getattr(args, "simulator", None) else "environment variable EHW_SIM"
        raise UserError(f"{source}: {simulator!r} is not a simulator; choose one of {', '.join(SIMULATORS)}")
    sample = getattr(args, "hdl_sample", None)
    if sample is None:
        sample = _from_env("EHW_HDL_SAMPLE")
    if sample is None:  # all of them on cocotb+Verilator, a spot check of 1 where all take hours
        sample = 0 if (args.backend == "cocotb" and simulator == "verilator") else 1
    if sample < 0:
        raise UserError(f"--hdl-sample must be a count of controllers (0: all), got {sample!r}")
    waves = getattr(args, "waves", None)
    if waves is None:
        waves = bool(_from_env("WAVES"))
    clock = getattr(args, "clock_hz", None)
    if clock is not None and not (math.isfinite(clock) and clock > 0):
        raise UserError(f"--clock-hz must be a positive frequency in Hz, got {clock!r}")
    if clock is None:  # None: the measured Fmax of results/fpga.json, else the named default
        clock = _from_env("EHW_CLOCK_HZ")
    _from_env("EHW_SYSTEM_P_MAX")  # checked here (one error line), read by cosim.boards.cocotb_backend
    return {"simulator": simulator, "hdl_sample": sample, "waves": waves,
            "clock_hz": None if clock is None else float(clock), **_link_settings(args)}


LINK_BACKENDS = ("serial", "uart", "emulated")  # the backends behind the UART host link (docs/host_link.md)


def _link_settings(args) -> dict:
    """``port``, ``port2`` (``--backend serial``) and ``baud`` (serial, uart): option >
    ``EHW_PORT`` / ``EHW_PORT2`` / ``EHW_BAUD`` > None, checked against the backend and ``--ga``."""
    backend, hardware = args.backend, getattr(args, "ga", "host") == "hardware"
    for name, backends in (("port", ("serial",)), ("port2", ("serial",)), ("baud", ("serial", "uart")),
                           ("line_faults", LINK_BACKENDS)):
        if getattr(args, name, None) is not None and backend not in backends:
            raise UserError(f"--{name.replace('_', '-')} is for --backend {' or '.join(backends)}, not {backend}")
    port = getattr(args, "port", None) or _from_env("EHW_PORT")
    port2 = getattr(args, "port2", None) or _from_env("EHW_PORT2")
    baud = getattr(args, "baud", None)
    if baud is not None and not (math.isfinite(baud) and baud > 0):
        raise UserError(f"--baud must be a positive baud rate, got {baud!r}")
    if baud is None:
        baud = _from_env("EHW_BAUD")
    if backend == "serial":
        board = "one ulx3s-learner board" if hardware else "a ULX3S (ulx3s-system) or, with --port2, two iCEBreakers"
        if not port:
            raise UserError(f"the serial backend needs a port: --port /dev/ttyUSB1 for {board} "
                            "(make sim BACKEND=serial PORT=...; or EHW_PORT=...)")
        if hardware and port2:
            raise UserError(f"--ga hardware on --backend serial is one ulx3s-learner board on --port; "
                            f"--port2 {port2!r} (EHW_PORT2) is the host GA's second iCEBreaker")
    return {"port": port if backend == "serial" else None, "port2": port2 if backend == "serial" else None,
            "baud": None if baud is None or backend not in ("serial", "uart") else float(baud),
            "line_faults": _line_faults(args, backend, hardware)}


def _line_faults(args, backend: str, hardware: bool) -> str | None:
    """``--line-faults`` (or ``EHW_LINE_FAULTS``) checked, as its canonical text; None: a clean line."""
    from cosim.link.faults import parse_faults

    given = getattr(args, "line_faults", None)
    text = given if given is not None else _from_env("EHW_LINE_FAULTS")
    faults = parse_faults(text, "--line-faults" if given is not None else "environment variable EHW_LINE_FAULTS")
    if faults is None or backend not in LINK_BACKENDS:
        return None
    if faults.reset and backend == "serial":
        raise UserError(f"--line-faults reset={faults.reset}: the host cannot reset a real board; power-cycle "
                        "or re-plug it during the run instead (the host recovers the same way)")
    if faults.reset and hardware:
        raise UserError(f"--line-faults reset={faults.reset}: with --ga hardware the host keeps no mirror "
                        "of the learning engine's population to restore after a reset (use --ga host)")
    return faults.to_text() or None


@contextlib.contextmanager
def hdl_environment(settings: dict):
    """The resolved settings in the process environment while a command runs (the backends read
    them there, and the cocotb simulator process inherits them); the old values come back after."""
    values = {"EHW_SIM": settings["simulator"], "EHW_HDL_SAMPLE": str(settings["hdl_sample"]),
              "WAVES": "1" if settings["waves"] else "0"}
    if settings["clock_hz"] is not None:  # else cosim.boards.hardware_time.measured_clock decides
        values["EHW_CLOCK_HZ"] = repr(settings["clock_hz"])
    values["EHW_LINE_FAULTS"] = settings.get("line_faults") or ""  # "": a clean line, whatever the caller's
    for key, name in (("port", "EHW_PORT"), ("port2", "EHW_PORT2"), ("baud", "EHW_BAUD")):
        if settings.get(key) is not None:  # the link backends read them there (cosim.link.boards)
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


def add_hdl_options(p) -> None:
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
    p.add_argument("--line-faults", default=None, metavar="flip=P,drop=P,silence=P,reset=N,seed=S",
                   help="--backend serial, uart or emulated: seeded faults on the link's line (bit flips "
                        "and dropped bytes per byte, silent replies per frame, N board resets, dead=K: "
                        "the line dies at frame K); the host detects and recovers each, the summary "
                        "counts them (cosim.link.faults; default: $EHW_LINE_FAULTS, else none)")
    p.add_argument("--clock-hz", type=float, default=None, metavar="HZ",
                   help="FPGA clock of the hardware-time figures (default: $EHW_CLOCK_HZ, else the "
                        "measured Fmax in results/fpga.json, else 12e6, the iCEBreaker's)")


# -- config files ---------------------------------------------------------------------------------


