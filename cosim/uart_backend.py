"""The ``uart`` board backend: the board top that goes into the bitstream, UART included
(``hdl.link.SystemLinkTop``), in Verilator through cocotb, reached by the host code of the
``serial`` backend (``cosim.link_host``, ``cosim.link_boards``) over a simulated serial line.

    make sim BACKEND=uart [BAUD=...] ARGS="--targets 4 --population 20"

The launching process writes ``system_link_top.v``, builds it in Verilator and runs this module's
cocotb test :func:`online_experiment_uart`. Inside the simulator: the clock (``SIM_CLK_HZ``), a
reset, cocotbext-uart's ``UartSource`` on the top's ``rx`` pin and ``UartSink`` on its ``tx``
pin, and the experiment loop of ``cosim.online`` in a thread (``cocotb.task.bridge``). The loop's
boards are ``cosim.link_boards``' over a :class:`SimulatedSerial`: pyserial's ``write`` /
``read`` / ``reset_input_buffer``, each a coroutine run in the simulator (``cocotb.task.resume``),
with the read timeout in *simulated* seconds. Only the stream differs from a real board.

The default baud here is the fastest the simulated clock allows (``hdl.uart.max_baud``: a run's
bytes cost simulated cycles, and every cycle costs wall time); ``BAUD=115200`` gives the real
link's timing (``cosim.link_bench`` measures it).
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

from cosim.boards import register_backend

TOPLEVEL = "system_link_top"
SIM_CLK_HZ = 25_000_000  # the ULX3S's oscillator; a whole number of ns a period (40)
CONFIG_ENV = "EHW_ONLINE_CONFIG"
OPTIONS_ENV = "EHW_UART_OPTIONS"
BAUD_ENV = "EHW_BAUD"

_active_line = None  # the SimulatedSerial of the running test (inside the simulator only)


def sim_baud_default() -> float:
    """``EHW_BAUD`` or the fastest baud of the simulated clock."""
    from hdl.uart import max_baud

    value = os.environ.get(BAUD_ENV, "")
    return float(value) if value else max_baud(SIM_CLK_HZ)


def board_timeout_s(baud: float) -> float:
    """The top's inter-byte timeout in simulation: 32 byte times (a real board's is 10 ms)."""
    return 32 * 10 / baud


def host_timeout_s(baud: float, p_max: int) -> float:
    """The host's reply timeout in simulated seconds: the longest frames both ways, the board's
    inter-byte timeout and the longest evaluation (p_max controllers on 256 states), twice over."""
    frames = (2 * 262 * 10) / baud
    evaluation = (p_max * 260 + 3000) / SIM_CLK_HZ
    return 2 * (frames + board_timeout_s(baud) + evaluation)


class SimulatedSerial:
    """A serial port onto a cocotb simulation: cocotbext-uart's source and sink on the top's pins.

    Called from the experiment's thread; each call runs in the simulator (``resume``).
    ``timeout`` is in simulated seconds (pyserial's ``read`` semantics: fewer bytes on timeout).
    """

    def __init__(self, dut, baud: float, timeout: float, name: str = TOPLEVEL):
        from cocotbext.uart import UartSink, UartSource

        self.port = f"simulated serial line of {name}"
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


def make_uart_boards(reflex: bool = True, distance_rule: str = "covered", check: bool = True):
    """The board pair over the running test's simulated line (inside the simulator only)."""
    from cosim.link_boards import boards_over
    from cosim.link_host import LinkClient

    if _active_line is None:
        raise RuntimeError("the uart backend runs the experiment inside the simulator: start it with "
                           "`python -m cosim.online --backend uart` (make sim BACKEND=uart)")
    return boards_over([LinkClient(_active_line)], reflex=reflex, check=check, distance_rule=distance_rule)


register_backend("uart", make_uart_boards)


# -- inside the simulator ---------------------------------------------------------------------------

try:
    import cocotb
except ImportError:  # pragma: no cover - cocotb is a dependency
    cocotb = None


async def start_top(dut, baud: float, timeout: float) -> SimulatedSerial:
    """Clock, synchronous reset, the evaluator's RAM sweep; the line to the top."""
    from cocotb.clock import Clock
    from cocotb.triggers import ClockCycles

    period_ps = round(1e12 / SIM_CLK_HZ)
    dut.rx.value = 1
    Clock(dut.clk, period_ps, unit="ps", impl="gpi").start(start_high=False)
    dut.rst.value = 1
    await ClockCycles(dut.clk, 2)
    dut.rst.value = 0
    await ClockCycles(dut.clk, 2100)  # Boot + Clear of the evaluator's RAM (2049 cycles)
    return SimulatedSerial(dut, baud, timeout)


def _experiment(config: dict, options: dict) -> dict:
    """The blocking experiment (runs in cocotb's bridge thread)."""
    from cosim.link_boards import link_summary
    from cosim.online import OnlineConfig, make_run, write_results

    cfg = OnlineConfig(**config)
    out = Path(options["out"])
    run = make_run(cfg, "uart", out, resume=bool(options.get("resume")),
                   progress=bool(options.get("progress")))
    run.run()
    summary = write_results(run, out, plots=bool(options.get("plots")))
    link = link_summary(run.controller, run.evaluator)
    (out / "link.json").write_text(json.dumps(link, indent=1) + "\n")
    return summary


if cocotb is not None:

    @cocotb.test()
    async def online_experiment_uart(dut):
        """The whole on-line experiment over the simulated line; options from the environment."""
        global _active_line
        from cocotb.task import bridge

        config = json.loads(os.environ[CONFIG_ENV])
        options = json.loads(os.environ[OPTIONS_ENV])
        _active_line = await start_top(dut, options["baud"], options["host_timeout_s"])
        try:
            await bridge(_experiment)(config, options)
        finally:
            _active_line = None


# -- the launching process --------------------------------------------------------------------------


def write_link_verilog(out_dir: Path, *, baud: float, p_max: int | None = None,
                       distance_rule: str = "covered") -> Path:
    """``system_link_top.v``: SystemLinkTop at ``SIM_CLK_HZ`` and ``baud`` (build id 0: the
    simulated top does not depend on the commit)."""
    from amaranth.back import verilog

    from cosim.cocotb_backend import icarus_time_zero_fix
    from hdl.link import SystemLinkTop

    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{TOPLEVEL}.v"
    top = SystemLinkTop(SIM_CLK_HZ, baud, p_max=p_max, distance_rule=distance_rule,
                        timeout_s=board_timeout_s(baud), build_id=0)
    path.write_text(icarus_time_zero_fix(verilog.convert(top, name=TOPLEVEL, emit_src=False)))
    return path


def prepare_uart_run(config, out: Path, *, baud: float, p_max: int | None = None,
                     build_name: str = TOPLEVEL, resume: bool = False, plots: bool = False,
                     progress: bool = False) -> tuple[Path, dict]:
    """The Verilog and the environment of :func:`online_experiment_uart` for ``config``."""
    from cosim.cocotb_run import SIM_BUILD
    from hdl.system_top import P_MAX

    p_max = P_MAX if p_max is None else int(p_max)
    source = write_link_verilog(SIM_BUILD / f"{build_name}_verilog", baud=baud, p_max=p_max,
                                distance_rule=config.distance_rule)
    options = {"out": str(out), "resume": resume, "plots": plots, "progress": progress,
               "baud": baud, "host_timeout_s": host_timeout_s(baud, p_max)}
    env = {CONFIG_ENV: json.dumps(config.to_dict()), OPTIONS_ENV: json.dumps(options),
           "EHW_SYSTEM_P_MAX": str(p_max)}
    return source, env


def run_online_uart(config, out: Path | str, *, baud: float | None = None, resume: bool = False,
                    plots: bool = False, progress: bool = False, build_name: str = TOPLEVEL,
                    p_max: int | None = None, waves: bool | None = None) -> dict:
    """Run the on-line experiment ``config`` over the simulated line (Verilator); returns the
    summary the test wrote (``out/summary.json``; ``out/link.json``: the link's figures)."""
    from cosim.cocotb_run import REPO_ROOT, run_cocotb

    baud = sim_baud_default() if baud is None else float(baud)
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)
    source, env = prepare_uart_run(config, out, baud=baud, p_max=p_max, build_name=build_name,
                                   resume=resume, plots=plots, progress=progress)
    run_cocotb(sources=[source], toplevel=TOPLEVEL, test_module="cosim.uart_backend",
               test_dir=REPO_ROOT, build_name=build_name, testcase="online_experiment_uart",
               extra_env=env, simulator="verilator", waves=waves)
    return json.loads((out / "summary.json").read_text())


def main_from_args(args, config) -> int:
    """``python -m cosim.online --backend uart ...``: launch the simulation, print its summary."""
    from cosim.online import summary_table

    baud = sim_baud_default()
    print(f"uart backend: SystemLinkTop in Verilator at {SIM_CLK_HZ / 1e6:g} MHz, {baud:,.0f} baud")
    summary = run_online_uart(config, args.out, baud=baud, resume=args.resume,
                              plots=not args.no_plots, progress=not args.no_progress)
    print(summary_table(summary))
    link = json.loads((Path(args.out) / "link.json").read_text())
    for role, figures in link.items():
        print(f"link ({role}): {figures['bytes_sent']:,} bytes sent, {figures['bytes_received']:,} "
              f"received, {figures['requests']:,} requests, {figures['resends']} resends")
    print(f"wrote {Path(args.out) / 'summary.json'}")
    return 0
