"""The host link's throughput in simulation: what the protocol actually carries at a baud.

    .venv/bin/python -m benchmarks bench_link          (EHW_BAUD=115200 by default)

SystemLinkTop (UART included) in Verilator at 25 MHz, driven by the serial backend's host code
over the uart backend's simulated line (cocotbext-uart), all times *simulated* seconds:

- ``POPULATION`` genomes loaded pipelined (``LinkClient.load_genomes``, the evaluator board's
  way) and ``STOP_AND_WAIT`` genomes one request at a time (``load_genome``): bytes a second
  each way and genomes a second (119 payload bytes a genome, SPEC section 8; a LOAD_GENOME frame
  is 128 bytes with its slot index, header and CRC);
- one EVALUATE of the population and its READ_RESULTS;
- ``INTERACTIONS`` execution steps (MOTION + OBSERVE), the controller board's traffic.

The line's ceiling is baud / 10 bytes a second each way (8N1).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from base import environ

POPULATION = 20
STOP_AND_WAIT = 5
INTERACTIONS = 20
P_MAX = 32
BAUD = 115_200
RESULT_ENV = "EHW_BENCH_OUT"

try:
    import cocotb
except ImportError:  # pragma: no cover
    cocotb = None


def _measure(line, now) -> dict:
    """The workload (in cocotb's bridge thread); ``now()`` gives the simulated time in s."""
    from cosim.link.host import LinkClient

    rng = np.random.default_rng(2026)
    client = LinkClient(line)
    client.identify()
    stats = client.stats
    out = {}

    def phase(name, job, count):
        sent, received, t0 = stats.bytes_sent, stats.bytes_received, now()
        job()
        dt = now() - t0
        out[f"{name}_s"] = dt
        out[f"{name}_bytes_to_board_per_s"] = (stats.bytes_sent - sent) / dt
        out[f"{name}_bytes_from_board_per_s"] = (stats.bytes_received - received) / dt
        out[f"{name}_per_s"] = count / dt

    pop = rng.integers(0, 1 << 19, (POPULATION, 50), dtype=np.uint32)
    phase("genomes_pipelined", lambda: client.load_genomes(pop), POPULATION)
    phase("genomes_stop_and_wait", lambda: [client.load_genome(i, pop[i]) for i in range(STOP_AND_WAIT)],
          STOP_AND_WAIT)
    for _ in range(40):
        client.observe(int(rng.integers(0, 64)), int(rng.integers(0, 8)), int(rng.integers(0, 64)),
                       False, int(rng.integers(0, 64)))
    phase("evaluate_and_read", lambda: (client.evaluate(POPULATION), client.read_results(0, POPULATION)), 1)

    def steps():
        for _ in range(INTERACTIONS):
            state = int(rng.integers(0, 256))
            motion = client.motion(state)
            client.observe(state, motion, int(rng.integers(0, 256)), False, int(rng.integers(0, 256)))

    phase("interactions", steps, INTERACTIONS)
    out["resends"] = stats.resends
    return out


if cocotb is not None:

    @cocotb.test()
    async def link_throughput(dut):
        from cocotb.task import bridge, resume
        from cocotb.utils import get_sim_time

        from cosim.link.simulated import host_timeout_s, start_top

        baud = environ.read("EHW_BAUD", BAUD)
        line = await start_top(dut, baud, host_timeout_s(baud, P_MAX), "hdl")

        async def sim_time():
            return get_sim_time("ns") * 1e-9

        figures = await bridge(_measure)(line, resume(sim_time))
        Path(environ.read(RESULT_ENV)).write_text(json.dumps(figures))


def run() -> dict:
    from cosim.boards.cocotb_run import REPO_ROOT, SIM_BUILD, run_cocotb
    from cosim.launch.uart_sim import TOPLEVEL, write_link_verilog
    from ga.genome import GENOME_BITS

    baud = environ.read("EHW_BAUD", BAUD)
    source = write_link_verilog(SIM_BUILD / "link_bench_verilog", baud=baud, p_max=P_MAX)
    with tempfile.TemporaryDirectory() as tmp:
        result = Path(tmp) / "link.json"
        run_cocotb(sources=[source], toplevel=TOPLEVEL, test_module="benchmarks.bench_link",
                   test_dir=REPO_ROOT, build_name="link_bench", testcase="link_throughput",
                   extra_env={RESULT_ENV: str(result), "EHW_BAUD": str(baud)}, simulator="verilator")
        figures = json.loads(result.read_text())
    genome_bytes = (GENOME_BITS + 7) // 8
    out = {
        "link_baud": baud,
        "link_line_bytes_per_s_ceiling": baud / 10,
        "link_genome_ceiling_per_s": baud / 10 / genome_bytes,
    }
    out.update({f"link_{key}": round(value, 3) if isinstance(value, float) else value
                for key, value in figures.items()})
    out["link_genome_payload_bytes_per_s"] = round(figures["genomes_pipelined_per_s"] * genome_bytes, 1)
    return out
