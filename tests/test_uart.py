# amaranth: UnusedElaboratable=no
"""hdl/uart.py against its Python model (``line_bits``, ``line_samples``, ``decode_line``).

Transmitter: random bytes sent back to back, the ``tx`` line sampled every cycle and decoded by
the model. Receiver: the model's line at the exact baud and 2 % fast and slow, every byte value
once plus random ones; a glitch shorter than half a bit is ignored; a stop bit of 0 is a framing
error, never a byte. The divisor rules: the fastest baud a clock allows, refusals quoting values.
"""

from __future__ import annotations

import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.uart import (DEFAULT_BAUD, MIN_DIVISOR, UART, UARTRx, UARTTx, decode_line, line_bits,
                      line_samples, max_baud, uart_divisor)

SEED = 13


def run_tx(data: bytes, divisor: int) -> list[int]:
    dut = UARTTx(divisor)
    samples: list[int] = []

    async def bench(ctx):
        for byte in data:
            ctx.set(dut.data.payload, byte)
            ctx.set(dut.data.valid, 1)
            await ctx.tick().until(dut.data.ready)
        ctx.set(dut.data.valid, 0)
        for _ in range(12 * divisor):
            await ctx.tick()

    async def probe(ctx):
        async for _, _, tx in ctx.tick().sample(dut.tx):
            samples.append(tx)

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.add_process(probe)
    sim.run()
    return samples


def run_rx(line: list[int], divisor: int) -> tuple[bytes, int]:
    dut = UARTRx(divisor)
    got, errors = bytearray(), [0]

    async def bench(ctx):
        ctx.set(dut.data.ready, 1)
        for level in line:
            ctx.set(dut.rx, level)
            await ctx.tick()
            if ctx.get(dut.data.valid):
                got.append(ctx.get(dut.data.payload))
            errors[0] += ctx.get(dut.frame_error)

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    return bytes(got), errors[0]


def test_line_model():
    assert line_bits(0x35) == [0, 1, 0, 1, 0, 1, 1, 0, 0, 1]
    assert decode_line(line_samples(b"\x00\xff\x5a", 8), 8) == (b"\x00\xff\x5a", 0)
    with pytest.raises(ValueError, match="256"):
        line_bits(256)


@pytest.mark.parametrize("divisor", [MIN_DIVISOR, 7, 16])
def test_tx_matches_the_model(divisor):
    data = bytes(np.random.default_rng(SEED).integers(0, 256, 24, dtype=np.uint8)) + b"\x00\xff"
    samples = run_tx(data, divisor)
    assert samples[0] == 1  # idle high from reset
    assert decode_line(samples, divisor) == (data, 0)
    # back to back: the whole message takes exactly 10 bits a byte (no gap)
    first = samples.index(0)
    assert len(samples) - first - samples[::-1].index(0) <= len(data) * 10 * divisor


# at 4 cycles a bit the sampling grid is a quarter bit: the fastest baud is checked unskewed
@pytest.mark.parametrize("divisor, skew", [(MIN_DIVISOR, 1.0), (16, 1.0), (16, 0.98), (16, 1.02)])
def test_rx_matches_the_model(divisor, skew):
    rng = np.random.default_rng(SEED)
    data = bytes(range(256)) if divisor == MIN_DIVISOR else bytes(rng.integers(0, 256, 40, dtype=np.uint8))
    got, errors = run_rx(line_samples(data, divisor * skew), divisor)
    assert (got, errors) == (data, 0)


def test_the_boards_real_divisor():
    """The divisor of the default baud on the iCEBreaker's clock (104; simulations of the whole
    link run at MIN_DIVISOR), both ways, the receiver also 2 % off."""
    divisor = uart_divisor(12e6, DEFAULT_BAUD)
    data = b"\xa5\x00\xff\x5a"
    assert decode_line(run_tx(data, divisor), divisor) == (data, 0)
    for skew in (1.0, 0.98, 1.02):
        assert run_rx(line_samples(data, divisor * skew), divisor) == (data, 0)


def test_rx_ignores_a_glitch_and_refuses_a_bad_stop_bit():
    divisor = 16
    glitch = [1] * 20 + [0] * (divisor // 2 - 3) + [1] * 40
    bad_stop = [1] * 20 + [b for b in line_bits(0xA5)[:-1] for _ in range(divisor)] + [0] * divisor + [1] * 40
    assert run_rx(glitch + line_samples(b"\x42", divisor), divisor) == (b"\x42", 0)
    assert run_rx(bad_stop + line_samples(b"\x42", divisor), divisor) == (b"\x42", 1)


def test_loopback_through_the_uart():
    dut = UART(clk_freq_hz=1e6, baud=125_000)  # divisor 8
    data = b"EHW\x00\xff"
    got = bytearray()

    async def bench(ctx):
        ctx.set(dut.rx_data.ready, 1)
        for byte in data:
            ctx.set(dut.tx_data.payload, byte)
            ctx.set(dut.tx_data.valid, 1)
            await ctx.tick().until(dut.tx_data.ready)
        ctx.set(dut.tx_data.valid, 0)

    async def loop(ctx):
        async for _, _, tx, valid, payload in ctx.tick().sample(dut.tx, dut.rx_data.valid, dut.rx_data.payload):
            ctx.set(dut.rx, tx)
            if valid:
                got.append(payload)

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.add_process(loop)
    sim.run_until(1e-6 * 8 * 10 * (len(data) + 2))
    assert bytes(got) == data


def test_divisor_rules():
    assert uart_divisor(12e6, 115_200) == 104
    assert uart_divisor(12e6, 3e6) == 4
    assert max_baud(12e6) == 3e6
    with pytest.raises(ValueError, match="too fast.*3,000,000"):
        uart_divisor(12e6, 4e6)
    with pytest.raises(ValueError, match="off"):
        uart_divisor(12e6, 2.6e6)  # divisor 5 gives 2.4 Mbaud, 8 % off
    with pytest.raises(ValueError, match="positive"):
        uart_divisor(0, 115_200)
    with pytest.raises(ValueError, match="divisor"):
        UARTRx(3)
