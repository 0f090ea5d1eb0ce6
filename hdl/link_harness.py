"""The link top with the host's end of its serial line beside it, for simulation (``LinkHarness``).

The harness around ``hdl.link_tops.SystemLinkTop`` or ``hdl.learner_link.LearnerLinkTop`` that
the ``uart`` backend builds in Verilator (``cosim.launch.uart_sim``); the host reaches it through
``cosim.link.simulated``'s serial lines.
"""

from __future__ import annotations

from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

HOST_FIFO_DEPTH = 512  # bytes the host may write ahead (two LOAD_GENOME frames are 256)


class LinkHarness(wiring.Component):
    """SystemLinkTop with the host's end of its serial line beside it, for simulation.

    ``internal`` = 0: the top's UART pins are the harness's ``rx`` / ``tx`` (a transmitter in
    Python drives them bit by bit: ``cosim.link.simulated.SimulatedSerial``). ``internal`` = 1: they are wired to
    a second ``hdl.uart.UART``, the host's USB-serial chip as it were, that sends the bytes
    written into a FIFO (``host_w_data`` / ``host_w_en``) and pulses ``host_r_valid`` with each
    byte it receives (``cosim.link.simulated.HarnessSerial``). The line between the two is the same bit-level
    8N1 signal; only the host's end costs one Python event a byte instead of one a bit.
    """

    def __init__(self, top):
        self.top = top
        super().__init__({
            "rx": In(1, init=1), "tx": Out(1, init=1), "internal": In(1),
            "host_w_data": In(8), "host_w_en": In(1), "host_w_rdy": Out(1),
            "host_r_data": Out(8), "host_r_valid": Out(1),
        })

    def elaborate(self, platform):
        from amaranth.hdl import Module, Mux
        from amaranth.lib.fifo import SyncFIFOBuffered

        from hdl.uart import UART

        m = Module()
        top = m.submodules.link = self.top
        host = m.submodules.host = UART(top.clk_freq_hz, top.baud)
        fifo = m.submodules.fifo = SyncFIFOBuffered(width=8, depth=HOST_FIFO_DEPTH)
        m.d.comb += [
            fifo.w_data.eq(self.host_w_data), fifo.w_en.eq(self.host_w_en), self.host_w_rdy.eq(fifo.w_rdy),
            host.tx_data.payload.eq(fifo.r_data), host.tx_data.valid.eq(fifo.r_rdy),
            fifo.r_en.eq(host.tx_data.ready),
            host.rx_data.ready.eq(1),
            self.host_r_data.eq(host.rx_data.payload), self.host_r_valid.eq(host.rx_data.valid),
            top.rx.eq(Mux(self.internal, host.tx, self.rx)),
            host.rx.eq(Mux(self.internal, top.tx, 1)),
            self.tx.eq(top.tx),
        ]
        return m
