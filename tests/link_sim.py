"""A byte stream (pyserial's ``write`` / ``read`` / ``reset_input_buffer``) onto a link top in
Amaranth's simulator, bit by bit through the line model of ``hdl.uart``; and a fault injector
that wraps any such stream. Shared by tests/test_link.py (Amaranth) and the uart backend's fault
tests (tests/cocotb_tb/tb_link_faults.py)."""

from __future__ import annotations

from collections import deque

from amaranth.sim import Simulator

from hdl.uart import line_bits

PERIOD_S = 1e-6


class AmaranthSerial:
    """The link top ``top`` (pins ``rx``/``tx``) in one Simulator; ``timeout`` in clock cycles."""

    def __init__(self, top, timeout_cycles: int, name: str = "amaranth line"):
        from hdl.uart import uart_divisor

        self.top = top
        self.port = name
        self.divisor = uart_divisor(top.clk_freq_hz, top.baud)
        self.timeout_cycles = timeout_cycles
        self.sim = Simulator(top)
        self.sim.add_clock(PERIOD_S)
        self.sim.add_process(self._line)
        self._levels: deque[int] = deque()  # host -> board, one level a cycle
        self._received = bytearray()  # board -> host, decoded
        self._countdown = None  # receiver model: cycles to the next sample point
        self._bits: list[int] = []
        self.cycles = 0

    async def _line(self, ctx):
        async for _, _, tx in ctx.tick().sample(self.top.tx):
            ctx.set(self.top.rx, self._levels.popleft() if self._levels else 1)
            self.cycles += 1
            self._sample(tx)

    def _sample(self, level: int) -> None:
        if self._countdown is None:
            if level == 0:  # a start edge: sample mid-bit from here
                self._countdown, self._bits = self.divisor // 2, []
            return
        self._countdown -= 1
        if self._countdown:
            return
        self._bits.append(level)
        self._countdown = self.divisor
        if self._bits[0] != 0:
            self._countdown = None  # a glitch
        elif len(self._bits) == 10:
            if self._bits[9] == 1:
                self._received.append(sum(b << i for i, b in enumerate(self._bits[1:9])))
            self._countdown = None

    def run_cycles(self, n: int) -> None:
        self.sim.run_until((self.cycles + n) * PERIOD_S + PERIOD_S / 2)

    def write(self, data: bytes) -> int:
        for byte in data:
            self._levels.extend(level for level in line_bits(byte) for _ in range(self.divisor))
        return len(data)

    def read(self, n: int) -> bytes:
        waited = 0
        step = 10 * self.divisor
        while len(self._received) < n and waited < self.timeout_cycles:
            self.run_cycles(step)
            waited += step
        out = bytes(self._received[:n])
        del self._received[:n]
        return out

    def reset_input_buffer(self) -> None:
        self._received.clear()


class FaultyStream:
    """Wraps a byte stream and damages it once: ``flip`` (XOR 0x10 into host byte number
    ``at``), ``drop`` (host byte ``at`` never sent), ``reply_flip`` (board byte ``at``), or
    ``silence`` (nothing reaches the board from host byte ``at`` on: a board that stops
    answering). Bytes are counted from the wrapper's creation."""

    KINDS = ("flip", "drop", "reply_flip", "silence")

    def __init__(self, stream, kind: str, at: int):
        if kind not in self.KINDS:
            raise ValueError(f"fault kind {kind!r}: one of {self.KINDS!r}")
        self.stream, self.kind, self.at = stream, kind, at
        self.port = getattr(stream, "port", "stream")
        self.sent = 0
        self.received = 0
        self.fired = False

    def write(self, data: bytes) -> int:
        out = bytearray()
        for byte in data:
            here = self.sent == self.at
            self.sent += 1
            if self.kind == "silence" and self.sent > self.at:
                self.fired = True
                continue
            if here and self.kind == "flip":
                byte ^= 0x10
                self.fired = True
            elif here and self.kind == "drop":
                self.fired = True
                continue
            out.append(byte)
        if out:
            self.stream.write(bytes(out))
        return len(data)

    def read(self, n: int) -> bytes:
        data = bytearray(self.stream.read(n))
        if self.kind == "reply_flip" and self.received <= self.at < self.received + len(data):
            data[self.at - self.received] ^= 0x10
            self.fired = True
        self.received += len(data)
        return bytes(data)

    def reset_input_buffer(self) -> None:
        self.stream.reset_input_buffer()
