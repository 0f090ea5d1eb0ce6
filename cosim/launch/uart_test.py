"""The cocotb test module of the ``uart`` backend: the whole on-line lifetime over the simulated line.

``cosim.launch.uart_sim`` builds the link top's harness and runs :func:`online_experiment_uart`
with the run's configuration and options in the environment (``cosim.launch.lifetime``). The
test clocks and resets the top, opens the simulated line (``cosim.link.simulated``) and runs the
lifetime of ``cosim.online.run`` in a thread on the ``uart`` boards; it writes ``summary.json``
and ``link.json`` into the output folder. Only cocotb imports this module.
"""

from __future__ import annotations

import cocotb

from cosim.launch.lifetime import lifetime_in_simulator, read_launch_env
from cosim.link import simulated


@cocotb.test()
async def online_experiment_uart(dut):
    """The whole on-line experiment over the simulated line; options from the environment."""
    from cocotb.task import bridge

    from cosim.link.boards import write_link_summary
    from cosim.link.faults import faulty

    config, options = read_launch_env()
    line = await simulated.start_top(dut, options["baud"], options["host_timeout_s"], options["line"],
                                     options.get("toplevel", simulated.TOPLEVEL))
    simulated.activate(faulty(line))  # --line-faults (EHW_LINE_FAULTS), if any
    try:
        run, _ = await bridge(lifetime_in_simulator)(config, options, "uart")
        write_link_summary(run, options["out"])
    finally:
        simulated.activate(None)
