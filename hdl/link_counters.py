"""IDENTIFY's reply and the READ_COUNTERS fields of the host link in one block RAM (docs/fpga.md).

The counters of ``COUNTERS_REPLY`` (frames executed, error replies, evaluator cycles) were 96
flip-flops with their adders, and IDENTIFY's 32 constant bytes a multiplexer, on top of a board
that hardly fits an iCE40UP5K. Here both are bytes of a small RAM (one EBR on the iCE40): the
sender reads a reply straight from it (``FrameSender`` fetches each payload byte by index, with
time for a synchronous read), and a counter is updated byte by byte, a read and a write a byte,
by an 8-bit adder: 2 x ``nbytes`` cycles (at most 12) an update.

Addresses: IDENTIFY's reply at :data:`IDENTIFY_BASE`, ``COUNTERS_REPLY`` at
:data:`COUNTERS_BASE` (little-endian, the reply's own layout).

A reset sweeps the counters to 0 (12 cycles, ``busy``): a RAM is not a register, and the
counters count since reset. An update must not be asked for while the sweep or another update
runs (``busy``): the link asks for at most one per frame (a frame is at least 7 bytes, 280 cycles
at the fastest baud).
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.link_protocol import COUNTERS_REPLY, IDENTIFY_REPLY, layout_bytes

IDENTIFY_BASE = 0
COUNTERS_BASE = 32
DEPTH = 64
ADDEND_BITS = 32  # the cycles of one EVALUATE (EVALUATE_REPLY)

assert layout_bytes(IDENTIFY_REPLY) <= COUNTERS_BASE - IDENTIFY_BASE
assert COUNTERS_BASE + layout_bytes(COUNTERS_REPLY) <= DEPTH


def _field(name: str) -> tuple[int, int]:
    """(address, bytes) of a ``COUNTERS_REPLY`` field."""
    field = data.Layout.cast(COUNTERS_REPLY)[name]
    assert field.offset % 8 == 0 and field.width % 8 == 0
    return COUNTERS_BASE + field.offset // 8, field.width // 8


class LinkCounters(wiring.Component):
    """The link's reply RAM: IDENTIFY's bytes and the counters, counted in place.

    Parameters
    ----------
    identity : bytes
        IDENTIFY's reply payload (``IDENTIFY_REPLY``), the RAM's initial contents there.

    Ports
    -----
    count_ok : In(1), count_rejected : In(1)
        Pulse: add 1 to ``frames_ok`` / ``frames_rejected``.
    add_cycles : In(1), cycles : In(32)
        Pulse: add ``cycles`` to ``evaluator_cycles``; ``cycles`` must hold until ``busy`` falls.
    busy : Out(1)
        An update is running (the read port is its own).
    addr : In(6), data : Out(8)
        Reading while not busy: the byte at ``addr`` appears on ``data`` one cycle later.
    """

    def __init__(self, identity: bytes):
        if len(identity) != layout_bytes(IDENTIFY_REPLY):
            raise ValueError(f"identity must be the {layout_bytes(IDENTIFY_REPLY)} bytes of IDENTIFY_REPLY, "
                             f"got {len(identity)!r}")
        self.identity = bytes(identity)
        super().__init__({
            "count_ok": In(1),
            "count_rejected": In(1),
            "add_cycles": In(1),
            "cycles": In(ADDEND_BITS),
            "busy": Out(1),
            "addr": In(range(DEPTH)),
            "data": Out(8),
        })

    def elaborate(self, platform):
        m = Module()
        init = [0] * DEPTH
        init[IDENTIFY_BASE:IDENTIFY_BASE + len(self.identity)] = self.identity
        ram = m.submodules.ram = Memory(shape=8, depth=DEPTH, init=init)
        rd = ram.read_port()
        wr = ram.write_port()

        first, n_bytes = COUNTERS_BASE, layout_bytes(COUNTERS_REPLY)
        address = Signal(range(DEPTH), init=first)  # the byte being updated (or swept)
        last = Signal(range(DEPTH))     # the field's last byte
        from_cycles = Signal()          # the addend is ``cycles`` (else 1)
        byte = Signal(range(8))         # its byte number in the field
        carry = Signal()
        wide = Cat(self.cycles, Signal(8 * 8 - ADDEND_BITS))  # 8 bytes: the field's can be 6
        addend = Mux(from_cycles, wide.word_select(byte, 8), byte == 0)
        total = Signal(9)
        m.d.comb += [self.data.eq(rd.data), total.eq(rd.data + addend + carry),
                     wr.addr.eq(address), wr.data.eq(total[:8])]

        def update(name, cycles):
            base, size = _field(name)
            m.d.sync += [address.eq(base), last.eq(base + size - 1), from_cycles.eq(cycles),
                         byte.eq(0), carry.eq(0)]
            m.next = "Read"

        with m.FSM(init="Clear"):
            with m.State("Clear"):  # after reset: every counter byte to 0
                m.d.comb += [self.busy.eq(1), wr.data.eq(0), wr.en.eq(1)]
                m.d.sync += address.eq(address + 1)
                with m.If(address == first + n_bytes - 1):
                    m.next = "Idle"
            with m.State("Idle"):
                m.d.comb += rd.addr.eq(self.addr)
                with m.If(self.count_ok):
                    update("frames_ok", False)
                with m.Elif(self.count_rejected):
                    update("frames_rejected", False)
                with m.Elif(self.add_cycles):
                    update("evaluator_cycles", True)
            with m.State("Read"):  # the byte's old value is read at this edge
                m.d.comb += [self.busy.eq(1), rd.addr.eq(address)]
                m.next = "Write"
            with m.State("Write"):
                m.d.comb += [self.busy.eq(1), wr.en.eq(1)]
                m.d.sync += [carry.eq(total[8]), address.eq(address + 1), byte.eq(byte + 1)]
                with m.If(address == last):
                    m.next = "Idle"
                with m.Else():
                    m.next = "Read"
        return m
