"""The simulated serial lines of the ``uart`` backend, and its boards over them.

Inside a cocotb simulation of the link top (``hdl.link_harness.LinkHarness``, started by
``cosim.launch.uart_sim``), the host code of the ``serial`` backend (``cosim.link.host``,
``cosim.link.boards``) talks to the top over one of two pyserial-like lines:

- :class:`SimulatedSerial`: cocotbext-uart's ``UartSource`` / ``UartSink`` on the top's pins;
- :class:`HarnessSerial`: the harness's host UART (one Python event a byte, not a bit).

Each call runs in the simulator (``cocotb.task.resume``), with the read timeout in *simulated*
seconds; only the stream differs from a real board. :func:`start_top` clocks and resets the top
and returns the line; :func:`make_uart_boards` and :func:`make_uart_learning_boards` (the
backend registry's ``uart`` factories) give the boards over the line of the running test.
Imports the link layer below it; the cocotb test that uses it is ``cosim.launch.uart_test``.
"""

from __future__ import annotations

import logging

from base.environ import UART_LINES
from cosim.boards.registry import register_backend
from ga.motions import DEFAULT_DISTANCE_RULE

TOPLEVEL = "system_link_top"
LEARNER_TOPLEVEL = "learner_link_top"  # --ga hardware: the LearnerLinkTop harness
SIM_CLK_HZ = 25_000_000  # the ULX3S's oscillator; a whole number of ns a period (40)
LINE_ENV = "EHW_UART_LINE"  # hdl (default: the host's UART in the simulation) or cocotbext
LINES = UART_LINES  # the values of LINE_ENV (base.environ reads it)

_active_line = None  # the line of the running test (inside the simulator only)


def activate(line) -> None:
    """Make ``line`` (or None) the line the ``uart`` boards are made over."""
    global _active_line
    _active_line = line


def board_timeout_s(baud: float) -> float:
    """The top's inter-byte timeout in simulation: 32 byte times (a real board's is 10 ms)."""
    return 32 * 10 / baud


def host_timeout_s(baud: float, p_max: int, busy_cycles: int | None = None) -> float:
    """The host's reply timeout in simulated seconds: the longest frames both ways, the board's
    inter-byte timeout and the longest evaluation (p_max controllers on 256 states; or
    ``busy_cycles``, the longest the board works before it replies), twice over."""
    frames = (2 * 262 * 10) / baud
    evaluation = (p_max * 260 + 3000 if busy_cycles is None else busy_cycles) / SIM_CLK_HZ
    return 2 * (frames + board_timeout_s(baud) + evaluation)


class SimulatedSerial:
    """A serial port onto a cocotb simulation: cocotbext-uart's source and sink on the top's pins.

    Called from the experiment's thread; each call runs in the simulator (``resume``).
    ``timeout`` is in simulated seconds (pyserial's ``read`` semantics: fewer bytes on timeout).
    """

    def __init__(self, dut, baud: float, timeout: float, name: str = TOPLEVEL):
        from cocotbext.uart import UartSink, UartSource

        self.port = f"simulated serial line of {name}"
        self.dut = dut
        self.timeout = timeout
        self.source = UartSource(dut.rx, baud=baud, bits=8, stop_bits=1)
        self.sink = UartSink(dut.tx, baud=baud, bits=8, stop_bits=1)
        for end in (dut.rx, dut.tx):  # cocotbext-uart logs every byte at INFO
            logging.getLogger(f"cocotb.{end._path}").setLevel(logging.WARNING)

    # coroutines (simulator side)

    async def _write(self, data: bytes) -> None:
        self.source.write_nowait(data)

    async def _read(self, n: int) -> bytes:
        from cocotb.triggers import First, Timer
        from cocotb.utils import get_sim_time

        deadline = get_sim_time("ns") + self.timeout * 1e9
        while self.sink.count() < n:
            left = deadline - get_sim_time("ns")
            if left <= 0:
                break
            # the sink's own wait() returns at once while any byte is queued: wait for the next one
            self.sink.sync.clear()
            await First(self.sink.sync.wait(), Timer(max(1, int(left)), "ns"))
        return bytes(self.sink.read_nowait(min(n, self.sink.count())))

    async def _flush(self) -> None:
        self.sink.clear()

    async def _board_reset(self) -> None:
        await reset_top(self.dut)
        self.sink.clear()

    # pyserial's interface (thread side)

    def _call(self, job, *args):
        from cocotb.task import resume

        return resume(job)(*args)

    def write(self, data: bytes) -> int:
        self._call(self._write, bytes(data))
        return len(data)

    def read(self, n: int) -> bytes:
        return self._call(self._read, int(n))

    def reset_input_buffer(self) -> None:
        self._call(self._flush)

    def board_reset(self) -> None:
        """A power glitch of the board top (``--line-faults reset=N``): its reset held 2 cycles,
        then its RAM sweep; whatever was on the line is lost."""
        self._call(self._board_reset)


class HarnessSerial:
    """A serial port onto :class:`LinkHarness`'s host UART (``internal`` = 1): one Python event
    a byte. Same interface and timeout semantics as :class:`SimulatedSerial`."""

    def __init__(self, dut, timeout: float, name: str = TOPLEVEL):
        import cocotb
        from cocotb.triggers import Event

        self.dut = dut
        self.port = f"simulated serial line of {name} (host UART in the simulation)"
        self.timeout = timeout
        self._received: list[int] = []
        self._arrived = Event()
        dut.internal.value = 1
        dut.host_w_en.value = 0
        self._monitor = cocotb.start_soon(self._receive())

    async def _receive(self) -> None:
        from cocotb.triggers import NextTimeStep, ReadOnly, RisingEdge

        valid = self.dut.host_r_valid
        while True:
            await RisingEdge(valid)  # one pulse a byte (ready is always 1)
            # the data once the time step has settled: Icarus calls back on valid's change before
            # it has updated data, which changes in the same step (Verilator: after both)
            await ReadOnly()
            byte = int(self.dut.host_r_data.value)
            await NextTimeStep()  # the reader this wakes may write to the top: not in ReadOnly
            self._received.append(byte)
            self._arrived.set()

    async def _write(self, data: bytes) -> None:
        from cocotb.triggers import RisingEdge

        dut = self.dut
        for byte in data:
            while not int(dut.host_w_rdy.value):
                dut.host_w_en.value = 0
                await RisingEdge(dut.clk)
            dut.host_w_data.value = byte
            dut.host_w_en.value = 1
            await RisingEdge(dut.clk)
        dut.host_w_en.value = 0

    async def _read(self, n: int) -> bytes:
        from cocotb.triggers import First, Timer
        from cocotb.utils import get_sim_time

        deadline = get_sim_time("ns") + self.timeout * 1e9
        while len(self._received) < n:
            left = deadline - get_sim_time("ns")
            if left <= 0:
                break
            self._arrived.clear()
            await First(self._arrived.wait(), Timer(max(1, int(left)), "ns"))
        out = bytes(self._received[:n])
        del self._received[:n]
        return out

    async def _flush(self) -> None:
        self._received.clear()

    async def _board_reset(self) -> None:
        self.dut.host_w_en.value = 0
        await reset_top(self.dut)
        self._received.clear()

    _call = SimulatedSerial._call
    board_reset = SimulatedSerial.board_reset
    write = SimulatedSerial.write
    read = SimulatedSerial.read
    reset_input_buffer = SimulatedSerial.reset_input_buffer


def make_uart_boards(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """The board pair over the running test's simulated line (inside the simulator only)."""
    from cosim.link.boards import boards_over
    from cosim.link.host import LinkClient

    if _active_line is None:
        raise RuntimeError("the uart backend runs the experiment inside the simulator: start it with "
                           "`ehw sim --backend uart` (make sim BACKEND=uart)")
    return boards_over([LinkClient(_active_line)], reflex=reflex, check=check, distance_rule=distance_rule)


register_backend("uart", make_uart_boards)


def make_uart_learning_boards(config, seed: int, population, reflex: bool = True,
                              distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """``--ga hardware``: (controller board, learning board) of the LearnerLinkTop over the running
    test's simulated line (inside the simulator only; ``cosim.boards.registry.make_learning_boards``)."""
    from cosim.link.host import LinkClient
    from cosim.link.learning import learning_boards_over

    if _active_line is None:
        raise RuntimeError("the uart backend runs the experiment inside the simulator: start it with "
                           "`ehw sim --backend uart --ga hardware` (make sim BACKEND=uart)")
    return learning_boards_over(LinkClient(_active_line), config, seed, population, reflex=reflex,
                                distance_rule=distance_rule, check=check)


async def reset_top(dut) -> None:
    """The top's synchronous reset, then the evaluators' RAM sweep (Boot + Clear, 2049 cycles)."""
    from cocotb.triggers import ClockCycles

    dut.rst.value = 1
    await ClockCycles(dut.clk, 2)
    dut.rst.value = 0
    await ClockCycles(dut.clk, 2100)


async def start_top(dut, baud: float, timeout: float, line: str = "cocotbext", name: str = TOPLEVEL):
    """Clock, synchronous reset, the evaluator's RAM sweep; the ``line`` to the top (``LINES``:
    :class:`HarnessSerial` or :class:`SimulatedSerial`)."""
    from cocotb.clock import Clock

    if line not in LINES:
        raise ValueError(f"{LINE_ENV}={line!r}: one of {LINES!r}")
    period_ps = round(1e12 / SIM_CLK_HZ)
    dut.rx.value = 1
    dut.internal.value = int(line == "hdl")
    dut.host_w_en.value = 0
    Clock(dut.clk, period_ps, unit="ps", impl="gpi").start(start_high=False)
    await reset_top(dut)
    return HarnessSerial(dut, timeout, name) if line == "hdl" else SimulatedSerial(dut, baud, timeout, name)
