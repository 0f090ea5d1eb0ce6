"""The one place the project reads environment variables: a typed reader per variable.

Every variable the code reads is a :class:`Variable` in :data:`VARIABLES` (its name, what a good
value is, the parser). :func:`read` gives the parsed value (``default`` when the variable is unset
or empty); a bad value is a :class:`base.errors.UserError` naming the variable and the value, so a
command ends with one ``error:`` line and exit 2, never a traceback. :func:`check_all` reads every
variable a user sets (``ehw`` calls it before any work), so a bad one is refused at the start even
when the command would have read it only later (or inside a simulator process).

Variables marked ``internal`` are set by a launcher for the process it starts (the run's config
for a cocotb test, ``cosim.launch.lifetime``); a bad one there is the launcher's bug, and
:func:`check_all` skips them. Imports only ``base``.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from typing import Callable

from base.errors import UserError

SIMULATORS = ("icarus", "verilator")  # the Verilog simulators of the cocotb backends
UART_LINES = ("hdl", "cocotbext")  # the simulated lines of --backend uart (cosim.link.simulated)


class BadEnvironment(UserError, ValueError):
    """An environment variable with a value the project cannot use."""


def _positive(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(value)
    return value


def _count(text: str) -> int:
    value = int(text.strip(), 10)
    if value < 0:
        raise ValueError(value)
    return value


def _positive_count(text: str) -> int:
    value = _count(text)
    if value < 1:
        raise ValueError(value)
    return value


def flag(text: str) -> bool:
    """1/true/yes/on or 0/false/no/off (any case)."""
    value = str(text).strip().lower()
    if value in ("1", "true", "yes", "on"):
        return True
    if value in ("0", "false", "no", "off"):
        return False
    raise ValueError(value)


def _choice(*choices: str) -> Callable[[str], str]:
    def parse(text: str) -> str:
        if text not in choices:
            raise ValueError(text)
        return text
    return parse


def _name(text: str) -> str:
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", text):
        raise ValueError(text)
    return text


def _text(text: str) -> str:
    if "\0" in text or text != text.strip():
        raise ValueError(text)
    return text


@dataclass(frozen=True)
class Variable:
    name: str
    what: str  # what a good value is, for the error line
    parse: Callable[[str], object]
    internal: bool = False  # set by a launcher for its child process, not by a user


VARIABLES = {v.name: v for v in (
    Variable("EHW_SIM", f"a Verilog simulator, one of {', '.join(SIMULATORS)}", _choice(*SIMULATORS)),
    Variable("EHW_HDL_SAMPLE", "a count of controllers (0: all)", _count),
    Variable("WAVES", "0 or 1", flag),
    Variable("EHW_CLOCK_HZ", "a positive frequency in Hz", _positive),
    Variable("EHW_FPGA_TARGET", "an FPGA target's name (hdl.fpga TARGETS)", _name),
    Variable("EHW_SYSTEM_P_MAX", "a population RAM depth >= 1", _positive_count),
    Variable("EHW_PORT", "a serial port (a device or a pyserial URL)", _text),
    Variable("EHW_PORT2", "a serial port (a device or a pyserial URL)", _text),
    Variable("EHW_BAUD", "a positive baud rate", _positive),
    Variable("EHW_UART_LINE", f"a simulated line, one of {', '.join(UART_LINES)}", _choice(*UART_LINES)),
    Variable("EHW_LINE_FAULTS", "a fault spec flip=P,drop=P,silence=P,reset=N,seed=S (cosim.link.faults)", _text),
    Variable("EHW_FPGA_TOOLS", "a folder of the FPGA tools", _text),
    Variable("EHW_CLOCK_INSIDE", "0 or 1", flag, internal=True),
    Variable("EHW_LEARNER_CONFIG", "JSON", json.loads, internal=True),
    Variable("EHW_ONLINE_CONFIG", "JSON", json.loads, internal=True),
    Variable("EHW_ONLINE_OPTIONS", "JSON", json.loads, internal=True),
    Variable("EHW_BENCH_OUT", "a file path", _text, internal=True),
)}


def raw(name: str) -> str | None:
    """The text of variable ``name``, None when unset or empty."""
    if name not in VARIABLES:
        raise KeyError(f"{name!r} is not one of the project's environment variables (base.environ)")
    value = os.environ.get(name, "")
    return value if value != "" else None


def read(name: str, default=None):
    """The parsed value of variable ``name`` (``default`` when unset or empty); a bad value is a
    UserError naming the variable, its value and what it must be."""
    value = raw(name)
    if value is None:
        return default
    variable = VARIABLES[name]
    try:
        return variable.parse(value)
    except (ValueError, TypeError):
        raise BadEnvironment(f"environment variable {name}={value!r}: must be {variable.what}") from None


def check_all() -> None:
    """Read every variable a user sets: the first bad one is a UserError."""
    for name, variable in VARIABLES.items():
        if not variable.internal:
            read(name)
