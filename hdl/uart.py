"""An 8N1 UART for the host link (SPEC section 8): Amaranth 0.5 and amaranth-boards ship none.

Line format: idle high; one start bit (0), eight data bits least significant first, one stop bit
(1); no parity. One bit lasts ``divisor`` = round(clk_freq_hz / baud) clock cycles.

- :class:`UARTTx`: takes a byte from its ``data`` stream when idle and shifts it out on ``tx``
  (10 bits, ``10 * divisor`` cycles a byte; back-to-back bytes leave no gap).
- :class:`UARTRx`: ``rx`` through a two-flip-flop synchronizer; a falling edge in idle starts a
  byte, the start bit is checked again in its middle (a shorter glitch is ignored), each data
  bit and the stop bit are sampled in their middles. A byte with a good stop bit appears on the
  ``data`` stream (held until taken; a byte that arrives while the last one is still untaken is
  dropped and ``overrun`` pulses); a stop bit of 0 pulses ``frame_error`` and drops the byte.
- :class:`UART`: both, with the pins ``rx`` / ``tx``: what a board top instantiates.

Fastest baud: the receiver finds the start edge up to one cycle late (after the synchronizer)
and samples each bit ``divisor // 2`` cycles after its start, so it needs ``divisor`` >= 4
(:data:`MIN_DIVISOR`): ``max_baud(clk)`` = clk / 4, 3 Mbaud at the iCEBreaker's 12 MHz. A baud
that ``clk_freq_hz`` cannot divide to within :data:`BAUD_TOLERANCE` is refused.

The Python model beside it: :func:`line_bits` (the levels of one byte on the line) and
:func:`decode_line` (a receiver over per-cycle samples); tests/test_uart.py checks both
directions of the RTL against them, at the exact baud and at +-2 %.
"""


from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

MIN_DIVISOR = 4  # clock cycles a bit, at least (see the module docstring)
BAUD_TOLERANCE = 0.02  # |achieved - asked| / asked: 8N1 receivers tolerate about 4 % in total
DEFAULT_BAUD = 115_200
BITS_PER_BYTE = 10  # start + 8 data + stop


def uart_divisor(clk_freq_hz: float, baud: float) -> int:
    """Clock cycles a bit for ``baud`` at ``clk_freq_hz``; refuses a baud the clock cannot make."""
    if not clk_freq_hz > 0:
        raise ValueError(f"clk_freq_hz must be positive, got {clk_freq_hz!r}")
    if not baud > 0:
        raise ValueError(f"baud must be positive, got {baud!r}")
    divisor = round(clk_freq_hz / baud)
    if divisor < MIN_DIVISOR:
        raise ValueError(f"baud {baud!r} is too fast for a {clk_freq_hz!r} Hz clock: the UART needs "
                         f"at least {MIN_DIVISOR} cycles a bit (at most {max_baud(clk_freq_hz):,.0f} baud)")
    error = abs(clk_freq_hz / divisor - baud) / baud
    if error > BAUD_TOLERANCE:
        raise ValueError(f"baud {baud!r} at {clk_freq_hz!r} Hz: the nearest divisor {divisor} gives "
                         f"{clk_freq_hz / divisor:,.0f} baud ({error:.1%} off, more than {BAUD_TOLERANCE:.0%})")
    return divisor


def max_baud(clk_freq_hz: float) -> float:
    """The fastest baud the UART runs at on a ``clk_freq_hz`` clock (``MIN_DIVISOR`` cycles a bit)."""
    return clk_freq_hz / MIN_DIVISOR


# -- the Python model ---------------------------------------------------------------------------


def line_bits(byte: int) -> list[int]:
    """The line levels of one 8N1 byte, one per bit: start, data LSB first, stop."""
    if not 0 <= byte < 256:
        raise ValueError(f"a byte is 0..255, got {byte!r}")
    return [0] + [(byte >> i) & 1 for i in range(8)] + [1]


def line_samples(data: bytes, cycles_per_bit: float, idle: int = 3) -> list[int]:
    """The line, one sample a clock cycle, carrying ``data`` at ``cycles_per_bit`` (may be
    fractional: a transmitter off the receiver's baud), ``idle`` bit times of idle before."""
    bits = [1] * idle + [b for byte in data for b in line_bits(byte)] + [1] * 2
    n = int(len(bits) * cycles_per_bit)
    return [bits[min(int(t / cycles_per_bit), len(bits) - 1)] for t in range(n)]


def decode_line(samples: list[int], divisor: int) -> tuple[bytes, int]:
    """A receiver over per-cycle samples: (the bytes with a good stop bit, framing errors)."""
    out, errors, t = bytearray(), 0, 0
    while t < len(samples):
        if samples[t] == 1:
            t += 1
            continue
        mid = t + divisor // 2  # the middle of the start bit
        if mid + 9 * divisor >= len(samples):
            break
        if samples[mid] != 0:
            t += 1
            continue
        bits = [samples[mid + (i + 1) * divisor] for i in range(8)]
        if samples[mid + 9 * divisor] == 1:
            out.append(sum(b << i for i, b in enumerate(bits)))
        else:
            errors += 1
        t = mid + 9 * divisor
    return bytes(out), errors


# -- the gateware -------------------------------------------------------------------------------


class UARTTx(wiring.Component):
    """8N1 transmitter.

    Parameters
    ----------
    divisor : int
        Clock cycles a bit (>= ``MIN_DIVISOR``; :func:`uart_divisor`).

    Ports
    -----
    data : In(stream.Signature(8))
        Bytes to send; taken (``ready``) only when the line is idle.
    tx : Out(1)
        The serial line (1 when idle).
    """

    data: In(stream.Signature(8))
    tx: Out(1, init=1)

    def __init__(self, divisor: int):
        if not isinstance(divisor, int) or divisor < MIN_DIVISOR:
            raise ValueError(f"divisor must be an int >= {MIN_DIVISOR}, got {divisor!r}")
        self.divisor = divisor
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        shreg = Signal(BITS_PER_BYTE, init=(1 << BITS_PER_BYTE) - 1)  # bit 0 is on the line
        timer = Signal(range(self.divisor))
        bits_left = Signal(range(BITS_PER_BYTE + 1))
        idle = bits_left == 0
        take = self.data.valid & idle

        m.d.comb += [
            self.tx.eq(shreg[0]),
            self.data.ready.eq(idle),
        ]
        with m.If(take):
            m.d.sync += [
                shreg.eq(Cat(0, self.data.payload, 1)),
                bits_left.eq(BITS_PER_BYTE),
                timer.eq(self.divisor - 1),
            ]
        with m.Elif(~idle):
            with m.If(timer == 0):
                m.d.sync += [
                    shreg.eq(Cat(shreg[1:], 1)),
                    bits_left.eq(bits_left - 1),
                    timer.eq(self.divisor - 1),
                ]
            with m.Else():
                m.d.sync += timer.eq(timer - 1)
        return m


class UARTRx(wiring.Component):
    """8N1 receiver.

    Parameters
    ----------
    divisor : int
        Clock cycles a bit (>= ``MIN_DIVISOR``).

    Ports
    -----
    rx : In(1)
        The serial line (asynchronous: synchronized inside).
    data : Out(stream.Signature(8))
        Received bytes, each held until taken.
    frame_error : Out(1)
        One-cycle pulse: a byte whose stop bit was 0 (dropped).
    overrun : Out(1)
        One-cycle pulse: a byte arrived while the previous one was untaken (the new one is dropped).
    """

    rx: In(1, init=1)
    data: Out(stream.Signature(8))
    frame_error: Out(1)
    overrun: Out(1)

    def __init__(self, divisor: int):
        if not isinstance(divisor, int) or divisor < MIN_DIVISOR:
            raise ValueError(f"divisor must be an int >= {MIN_DIVISOR}, got {divisor!r}")
        self.divisor = divisor
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        rx = Signal(init=1)
        m.submodules.sync = FFSynchronizer(self.rx, rx, init=1)
        timer = Signal(range(self.divisor))
        bit = Signal(range(8))
        shreg = Signal(8)
        tick = timer == 0

        with m.If(self.data.ready):
            m.d.sync += self.data.valid.eq(0)
        m.d.sync += [self.frame_error.eq(0), self.overrun.eq(0)]

        with m.If(~tick):
            m.d.sync += timer.eq(timer - 1)
        with m.FSM(init="Idle"):
            with m.State("Idle"):
                with m.If(~rx):
                    # the edge is seen up to 1 cycle late: the middle of the start bit is
                    # divisor // 2 cycles on (this cycle counts as the first)
                    m.d.sync += timer.eq(self.divisor // 2 - 1)
                    m.next = "Start"
            with m.State("Start"):
                with m.If(tick):
                    with m.If(rx):
                        m.next = "Idle"  # a glitch, not a start bit
                    with m.Else():
                        m.d.sync += [timer.eq(self.divisor - 1), bit.eq(0)]
                        m.next = "Data"
            with m.State("Data"):
                with m.If(tick):
                    m.d.sync += [shreg.eq(Cat(shreg[1:], rx)), timer.eq(self.divisor - 1),
                                 bit.eq(bit + 1)]
                    with m.If(bit == 7):
                        m.next = "Stop"
            with m.State("Stop"):
                with m.If(tick):
                    # back to Idle in the middle of the stop bit: a transmitter up to half a bit
                    # faster still has its next start edge seen
                    with m.If(~rx):
                        m.d.sync += self.frame_error.eq(1)
                    with m.Elif(self.data.valid & ~self.data.ready):
                        m.d.sync += self.overrun.eq(1)
                    with m.Else():
                        m.d.sync += [self.data.payload.eq(shreg), self.data.valid.eq(1)]
                    m.next = "Idle"
        return m


class UART(wiring.Component):
    """8N1 transmitter + receiver on the pins ``rx`` / ``tx`` at ``baud``.

    Parameters
    ----------
    clk_freq_hz : float
        The ``sync`` clock.
    baud : float
        Bits a second (default 115,200); :func:`uart_divisor` refuses one the clock cannot make.

    Ports
    -----
    rx : In(1), tx : Out(1)
        The serial line's two wires (board side: ``rx`` from the host's TX).
    rx_data : Out(stream.Signature(8)); tx_data : In(stream.Signature(8))
        Received bytes, bytes to send.
    frame_error : Out(1), overrun : Out(1)
        Receiver pulses (:class:`UARTRx`).
    """

    rx: In(1, init=1)
    tx: Out(1, init=1)
    rx_data: Out(stream.Signature(8))
    tx_data: In(stream.Signature(8))
    frame_error: Out(1)
    overrun: Out(1)

    def __init__(self, clk_freq_hz: float, baud: float = DEFAULT_BAUD):
        self.clk_freq_hz = clk_freq_hz
        self.baud = baud
        self.divisor = uart_divisor(clk_freq_hz, baud)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        rx = m.submodules.rx = UARTRx(self.divisor)
        tx = m.submodules.tx = UARTTx(self.divisor)
        m.d.comb += [rx.rx.eq(self.rx), self.tx.eq(tx.tx),
                     self.frame_error.eq(rx.frame_error), self.overrun.eq(rx.overrun)]
        wiring.connect(m, wiring.flipped(self.rx_data), rx.data)
        wiring.connect(m, wiring.flipped(self.tx_data), tx.data)
        return m
