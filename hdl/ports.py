"""Ports and wire formats shared by several EHW components, and the one host-side driver of each.

Each contract is defined once here and used by every component that has it (STYLE.md: a port
used by several components is a ``wiring.Signature``; a wire format is a ``data.StructLayout``
used on both sides):

- ``RowWriteSignature(k)``: the row-write port of SPEC section 8 (``addr``, ``data``, ``we``), by
  which the host (or the system top's population streamer) fills a board's configuration one
  19-bit row word a cycle. ``ControllerEHW.row`` and ``EvaluatorEHW.row`` are ``In`` of it; a top
  forwards one with ``wiring.connect(m, wiring.flipped(self.ctl_row), ctl.row)``. In the generated
  Verilog a port ``row`` of it is ``row__addr``, ``row__data``, ``row__we``.
- ``ModelWriteSignature()``: the evaluator's world-model write port (entry (``state``,
  ``motion``) := {``next``, ``crash``, ``valid``} when ``we``).
- ``RateWriteSignature()``: the evaluator's failure-rate write port (code of (``state``,
  ``motion``) := ``code`` when ``we``; ``ga.fail_rates``).
- ``ModelEntry``: one world-model RAM word (9 bits: the port's {next, crash, valid} coded so that
  the 2048 entries fit one 2048 x 9 block RAM); ``RESULT_LAYOUT``: the evaluator's result word
  (crashes, loops, distance, fails), packed by the system top's results RAM and unpacked by the
  host with ``unpack_result``.

Host side, for any simulator: a *pins* object has ``set(name, value)``, ``get(name) -> int`` and
``await tick()`` (inputs set before ``tick`` are sampled by the next rising edge; after it returns
the registered outputs show that edge's result), with names as in the generated Verilog
(``ctl_row__addr``). ``AmaranthPins`` adapts an Amaranth testbench context, ``CocotbPins`` a
cocotb DUT; ``write_rows`` is the one row-write driver every testbench and host uses.
"""

# (No ``from __future__ import annotations``: ``data.Struct`` reads its fields from the values of
# its annotations, and skips string ones silently.)

from amaranth.hdl import Mux
from amaranth.lib import data, wiring
from amaranth.lib.wiring import Out

from ga.fail_rates import FAIL_BITS, RATE_BITS
from ga.genome import N_ROWS, ROW_BITS
from ga.motions import N_INPUTS, N_OUTPUTS, N_STATES

COUNT_BITS = N_STATES.bit_length()  # 9: counts 0..256 (states, crashes, loops)
DISTANCE_BITS = 16


class ModelEntry(data.Struct):
    """One world-model RAM word (SPEC section 8), 9 bits: the 2048 entries fit one 2048 x 9
    block RAM (an ECP5 DP16KD), so the evaluator's trace loop closes on one block with no output
    multiplexer (docs/learner.md, "Resources and clock").

    The port's entry {next, crash, valid} (``ModelWriteSignature``) is coded as ``moves`` =
    valid and not crash (the trace follows ``next``) and, when it does not move, ``next`` (which
    the trace never reads then) says why: ``UNKNOWN`` (0, so the all-zero word the Clear sweep
    writes is an unknown entry) or ``CRASH``. Written by :meth:`store`, read by ``moves``,
    ``next`` and :meth:`crashed`: the only places that know the coding.
    """

    next: N_INPUTS
    moves: 1

    UNKNOWN = 0  # next of a word that does not move: the transition is unknown
    CRASH = 1  # next of a word that does not move: the motion crashed

    def store(self, next_state, crash, valid):
        """The statements that set this word to the port's entry {next, crash, valid}."""
        moves = valid & ~crash
        return [self.moves.eq(moves),
                self.next.eq(Mux(moves, next_state, Mux(valid, self.CRASH, self.UNKNOWN)))]

    def crashed(self):
        """The entry records a crash (valid and crash at the port)."""
        return ~self.moves & (self.next == self.CRASH)


# The evaluator's result word: what one evaluation returns to the host (SPEC section 7: the
# hardware returns crashes, loops and distance; the host turns them into the fitness), and the
# failure-rate count F (``ga.fail_rates``; the host ignores it without --fail-rates).
RESULT_LAYOUT = data.StructLayout({
    "crashes": COUNT_BITS,
    "loops": COUNT_BITS,
    "distance": DISTANCE_BITS,
    "fails": FAIL_BITS,
})


def row_addr_bits(k: int) -> int:
    """Width of a row address for ``k`` rows (6 for the paper's 50)."""
    return max(1, (k - 1).bit_length())


class RowWriteSignature(wiring.Signature):
    """Row-write port, from the writer's side: ``addr`` (row 0..k-1; larger ones are ignored by
    the boards), ``data`` (the 19-bit row word of SPEC section 3), ``we`` (write at the next edge).
    """

    def __init__(self, k: int = N_ROWS):
        self.k = k
        super().__init__({
            "addr": Out(row_addr_bits(k)),
            "data": Out(ROW_BITS),
            "we": Out(1),
        })

    def __eq__(self, other):
        return isinstance(other, RowWriteSignature) and self.k == other.k

    def __hash__(self):
        return hash((RowWriteSignature, self.k))

    def __repr__(self):
        return f"RowWriteSignature({self.k})"


class ModelWriteSignature(wiring.Signature):
    """World-model write port, from the writer's (host's) side: entry (``state``, ``motion``) :=
    {``next``, ``crash``, ``valid``} at the next edge when ``we``."""

    def __init__(self):
        super().__init__({
            "state": Out(N_INPUTS),
            "motion": Out(N_OUTPUTS),
            "next": Out(N_INPUTS),
            "crash": Out(1),
            "valid": Out(1),
            "we": Out(1),
        })

    def __eq__(self, other):
        return isinstance(other, ModelWriteSignature)

    def __hash__(self):
        return hash(ModelWriteSignature)

    def __repr__(self):
        return "ModelWriteSignature()"


class RateWriteSignature(wiring.Signature):
    """Failure-rate write port, from the writer's (host's) side: the rate code of (``state``,
    ``motion``) := ``code`` (``ga.fail_rates``) at the next edge when ``we``."""

    def __init__(self):
        super().__init__({
            "state": Out(N_INPUTS),
            "motion": Out(N_OUTPUTS),
            "code": Out(RATE_BITS),
            "we": Out(1),
        })

    def __eq__(self, other):
        return isinstance(other, RateWriteSignature)

    def __hash__(self):
        return hash(RateWriteSignature)

    def __repr__(self):
        return "RateWriteSignature()"


def unpack_result(word: int) -> tuple[int, int, int, int]:
    """(crashes, loops, distance, fails) from a result word (``RESULT_LAYOUT``)."""
    result = RESULT_LAYOUT.from_bits(int(word))
    return int(result.crashes), int(result.loops), int(result.distance), int(result.fails)


def pack_result(crashes: int, loops: int, distance: int, fails: int) -> int:
    """The result word of (crashes, loops, distance, fails): the inverse of ``unpack_result``."""
    const = RESULT_LAYOUT.const({"crashes": crashes, "loops": loops, "distance": distance, "fails": fails})
    return const.as_value().value


# -- host side -------------------------------------------------------------------------------------


class AmaranthPins:
    """Pins over an Amaranth testbench context: ``ctl_row__addr`` is ``dut.ctl_row.addr``."""

    def __init__(self, dut, ctx=None):
        self.dut = dut
        self.ctx = ctx  # the testbench context (set later by a serving testbench)
        self._signals = {}

    def signal(self, name: str):
        signal = self._signals.get(name)
        if signal is None:
            signal = self.dut
            for part in name.split("__"):
                signal = getattr(signal, part)
            self._signals[name] = signal
        return signal

    def set(self, name: str, value: int) -> None:
        self.ctx.set(self.signal(name), value)

    def get(self, name: str) -> int:
        value = self.ctx.get(self.signal(name))
        if isinstance(value, data.Const):  # a port of a layout: its raw bits, as in the Verilog
            value = value.as_value().value
        return int(value)

    async def tick(self) -> None:
        await self.ctx.tick()

    async def wait(self, name: str) -> None:
        """Tick until ``name`` reads 1 (at least one tick)."""
        await self.ctx.tick()
        while not self.get(name):
            await self.ctx.tick()


class CocotbPins:
    """Pins over cocotb handles: inputs are set after a falling edge, the rising edge in
    mid-cycle samples them, outputs are read at the next falling edge."""

    def __init__(self, dut, clock_name: str = "clk"):
        from cocotb.triggers import FallingEdge

        self.dut = dut
        self._handles = {}
        self._falling = FallingEdge(getattr(dut, clock_name))

    def _handle(self, name):
        handle = self._handles.get(name)
        if handle is None:
            handle = self._handles[name] = getattr(self.dut, name)
        return handle

    def set(self, name: str, value: int) -> None:
        self._handle(name).value = value

    def get(self, name: str) -> int:
        value = self._handle(name).value
        try:
            return value.to_unsigned() if hasattr(value, "to_unsigned") else int(value)
        except ValueError:
            raise ValueError(f"{name} reads {value!s}: not a number (X or Z bits)") from None

    async def tick(self) -> None:
        await self._falling

    async def wait(self, name: str) -> None:
        """Until ``name`` has risen, then to the falling edge after it (as ticking until it reads 1)."""
        from cocotb.triggers import RisingEdge

        await RisingEdge(self._handle(name))
        await self._falling


async def write_rows(pins, port: str, rows, strobe: str | None = None, first_row: int = 0) -> int:
    """Write the row words ``rows`` through the row-write port named ``port`` (e.g. ``"row"``,
    ``"ctl_row"``), one a cycle from row ``first_row`` on, raising ``strobe`` (e.g. ``"commit"``
    or ``"start"``) with the last one; leaves ``we`` and ``strobe`` low. Returns the cycles spent
    (one per row)."""
    last = len(rows) - 1
    for r, word in enumerate(rows):
        pins.set(f"{port}__addr", first_row + r)
        pins.set(f"{port}__data", int(word))
        pins.set(f"{port}__we", 1)
        if strobe is not None:
            pins.set(strobe, int(r == last))
        await pins.tick()
    pins.set(f"{port}__we", 0)
    if strobe is not None:
        pins.set(strobe, 0)
    return len(rows)
