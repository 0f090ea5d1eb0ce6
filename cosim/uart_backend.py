"""The ``uart`` board backend: the board top that goes into the bitstream, UART included
(``hdl.link_tops.SystemLinkTop``), in Verilator through cocotb, reached by the host code of the
``serial`` backend (``cosim.link_host``, ``cosim.link_boards``) over a simulated serial line.

    make sim BACKEND=uart [BAUD=...] ARGS="--targets 4 --population 20"
    make sim BACKEND=uart ARGS="--ga hardware --targets 2 --population 6 --lanes 2"

With ``--ga hardware`` the top is ``hdl.learner_link.LearnerLinkTop`` (the ``ulx3s-learner``
bitstream's: the controller board beside the learning engine, built for the run's population,
tournament, lanes and rates) and the boards are ``cosim.link_learning``'s, over the same line.

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

from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from cosim.boards import register_backend
from ga.motions import DEFAULT_DISTANCE_RULE

TOPLEVEL = "system_link_top"
LEARNER_TOPLEVEL = "learner_link_top"  # --ga hardware: the LearnerLinkTop harness
SIM_CLK_HZ = 25_000_000  # the ULX3S's oscillator; a whole number of ns a period (40)
CONFIG_ENV = "EHW_ONLINE_CONFIG"
OPTIONS_ENV = "EHW_UART_OPTIONS"
BAUD_ENV = "EHW_BAUD"
LINE_ENV = "EHW_UART_LINE"  # hdl (default: the host's UART in the simulation) or cocotbext
LINES = ("hdl", "cocotbext")
HOST_FIFO_DEPTH = 512  # bytes the host may write ahead (two LOAD_GENOME frames are 256)

_active_line = None  # the SimulatedSerial of the running test (inside the simulator only)


def sim_baud_default() -> float:
    """``EHW_BAUD`` or the fastest baud of the simulated clock."""
    from hdl.uart import max_baud

    value = os.environ.get(BAUD_ENV, "")
    return float(value) if value else max_baud(SIM_CLK_HZ)


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


class LinkHarness(wiring.Component):
    """SystemLinkTop with the host's end of its serial line beside it, for simulation.

    ``internal`` = 0: the top's UART pins are the harness's ``rx`` / ``tx`` (a transmitter in
    Python drives them bit by bit: :class:`SimulatedSerial`). ``internal`` = 1: they are wired to
    a second ``hdl.uart.UART``, the host's USB-serial chip as it were, that sends the bytes
    written into a FIFO (``host_w_data`` / ``host_w_en``) and pulses ``host_r_valid`` with each
    byte it receives (:class:`HarnessSerial`). The line between the two is the same bit-level
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
        from cocotb.triggers import RisingEdge

        valid = self.dut.host_r_valid
        while True:
            await RisingEdge(valid)  # one pulse a byte (ready is always 1)
            self._received.append(int(self.dut.host_r_data.value))
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

    _call = SimulatedSerial._call
    write = SimulatedSerial.write
    read = SimulatedSerial.read
    reset_input_buffer = SimulatedSerial.reset_input_buffer


def make_uart_boards(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """The board pair over the running test's simulated line (inside the simulator only)."""
    from cosim.link_boards import boards_over
    from cosim.link_host import LinkClient

    if _active_line is None:
        raise RuntimeError("the uart backend runs the experiment inside the simulator: start it with "
                           "`python -m cosim.online --backend uart` (make sim BACKEND=uart)")
    return boards_over([LinkClient(_active_line)], reflex=reflex, check=check, distance_rule=distance_rule)


register_backend("uart", make_uart_boards)


def make_uart_learning_boards(config, seed: int, population, reflex: bool = True,
                              distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """``--ga hardware``: (controller board, learning board) of the LearnerLinkTop over the running
    test's simulated line (inside the simulator only; ``cosim.boards.make_learning_boards``)."""
    from cosim.link_host import LinkClient
    from cosim.link_learning import learning_boards_over

    if _active_line is None:
        raise RuntimeError("the uart backend runs the experiment inside the simulator: start it with "
                           "`ehw sim --backend uart --ga hardware` (make sim BACKEND=uart)")
    return learning_boards_over(LinkClient(_active_line), config, seed, population, reflex=reflex,
                                distance_rule=distance_rule, check=check)


# -- inside the simulator ---------------------------------------------------------------------------

try:
    import cocotb
except ImportError:  # pragma: no cover - cocotb is a dependency
    cocotb = None


async def start_top(dut, baud: float, timeout: float, line: str = "cocotbext", name: str = TOPLEVEL):
    """Clock, synchronous reset, the evaluator's RAM sweep; the ``line`` to the top (``LINES``:
    :class:`HarnessSerial` or :class:`SimulatedSerial`)."""
    from cocotb.clock import Clock
    from cocotb.triggers import ClockCycles

    if line not in LINES:
        raise ValueError(f"{LINE_ENV}={line!r}: one of {LINES!r}")
    period_ps = round(1e12 / SIM_CLK_HZ)
    dut.rx.value = 1
    dut.internal.value = int(line == "hdl")
    dut.host_w_en.value = 0
    Clock(dut.clk, period_ps, unit="ps", impl="gpi").start(start_high=False)
    dut.rst.value = 1
    await ClockCycles(dut.clk, 2)
    dut.rst.value = 0
    await ClockCycles(dut.clk, 2100)  # Boot + Clear of the evaluators' RAMs (2049 cycles)
    return HarnessSerial(dut, timeout, name) if line == "hdl" else SimulatedSerial(dut, baud, timeout, name)


def _experiment(config: dict, options: dict) -> dict:
    """The blocking experiment (runs in cocotb's bridge thread)."""
    from cosim.link_boards import write_link_summary
    from cosim.online import OnlineConfig, make_run
    from cosim.online_report import write_results

    cfg = OnlineConfig(**config)
    out = Path(options["out"])
    run = make_run(cfg, "uart", out, resume=bool(options.get("resume")),
                   progress=bool(options.get("progress")))
    run.run()
    summary = write_results(run, out, plots=bool(options.get("plots")))
    write_link_summary(run, out)
    return summary


if cocotb is not None:

    @cocotb.test()
    async def online_experiment_uart(dut):
        """The whole on-line experiment over the simulated line; options from the environment."""
        global _active_line
        from cocotb.task import bridge

        config = json.loads(os.environ[CONFIG_ENV])
        options = json.loads(os.environ[OPTIONS_ENV])
        _active_line = await start_top(dut, options["baud"], options["host_timeout_s"], options["line"],
                                       options.get("toplevel", TOPLEVEL))
        try:
            await bridge(_experiment)(config, options)
        finally:
            _active_line = None


# -- the launching process --------------------------------------------------------------------------


def write_link_verilog(out_dir: Path, *, baud: float, p_max: int | None = None,
                       distance_rule: str = DEFAULT_DISTANCE_RULE, ga_config=None) -> Path:
    """``system_link_top.v``: :class:`LinkHarness` around SystemLinkTop at ``SIM_CLK_HZ`` and
    ``baud`` (build id 0: the simulated top does not depend on the commit); with ``ga_config``
    (``--ga hardware``) ``learner_link_top.v`` around LearnerLinkTop for that engine."""
    from amaranth.back import verilog

    from cosim.cocotb_run import icarus_time_zero_fix

    out_dir.mkdir(parents=True, exist_ok=True)
    timing = {"timeout_s": board_timeout_s(baud), "build_id": 0}
    if ga_config is None:
        from hdl.link_tops import SystemLinkTop

        name, top = TOPLEVEL, SystemLinkTop(SIM_CLK_HZ, baud, p_max=p_max, distance_rule=distance_rule, **timing)
    else:
        from hdl.learner_link import LearnerLinkTop

        name, top = LEARNER_TOPLEVEL, LearnerLinkTop(SIM_CLK_HZ, baud, config=ga_config,
                                                     distance_rule=distance_rule, **timing)
    path = out_dir / f"{name}.v"
    text = icarus_time_zero_fix(verilog.convert(LinkHarness(top), name=name, emit_src=False))
    if not path.exists() or path.read_text() != text:  # an unchanged file keeps the build's stamp
        path.write_text(text)
    return path


def learner_build_name(ga_config, distance_rule: str, baud: float) -> str:
    """The build folder of the LearnerLinkTop harness for ``ga_config``: one build per circuit."""
    import hashlib

    key = json.dumps({"config": ga_config.to_dict(), "rule": distance_rule, "baud": baud}, sort_keys=True)
    return f"{LEARNER_TOPLEVEL}_{hashlib.sha256(key.encode()).hexdigest()[:10]}"


def prepare_uart_run(config, out: Path, *, baud: float, p_max: int | None = None,
                     build_name: str = TOPLEVEL, resume: bool = False, plots: bool = False,
                     progress: bool = False) -> tuple[Path, dict]:
    """The Verilog and the environment of :func:`online_experiment_uart` for ``config`` (with
    ``--ga hardware``: the LearnerLinkTop for its engine, ``p_max`` unused)."""
    from cosim.cocotb_run import SIM_BUILD
    from hdl.system_top import P_MAX

    line = os.environ.get(LINE_ENV) or "hdl"
    if line not in LINES:
        raise ValueError(f"{LINE_ENV}={line!r}: one of {LINES!r}")
    env = {CONFIG_ENV: json.dumps(config.to_dict())}
    if config.ga == "hardware":
        from cosim.learning_phase import hardware_ga_config
        from ga.hardware_ga import learn_cycles

        ga_config = hardware_ga_config(config)
        source = write_link_verilog(SIM_BUILD / f"{build_name}_verilog", baud=baud, ga_config=ga_config,
                                    distance_rule=config.distance_rule)
        # the longest reply: a LEARN on a full model (or the population's upload, for small ones)
        timeout = host_timeout_s(baud, ga_config.population,
                                 busy_cycles=learn_cycles(256, ga_config, config.generations_per_phase))
        toplevel = LEARNER_TOPLEVEL
    else:
        p_max = P_MAX if p_max is None else int(p_max)
        source = write_link_verilog(SIM_BUILD / f"{build_name}_verilog", baud=baud, p_max=p_max,
                                    distance_rule=config.distance_rule)
        timeout, toplevel = host_timeout_s(baud, p_max), TOPLEVEL
        env["EHW_SYSTEM_P_MAX"] = str(p_max)
    options = {"out": str(out), "resume": resume, "plots": plots, "progress": progress,
               "baud": baud, "host_timeout_s": timeout, "line": line, "toplevel": toplevel}
    env[OPTIONS_ENV] = json.dumps(options)
    return source, env


def run_online_uart(config, out: Path | str, *, baud: float | None = None, resume: bool = False,
                    plots: bool = False, progress: bool = False, build_name: str | None = None,
                    p_max: int | None = None, waves: bool | None = None) -> dict:
    """Run the on-line experiment ``config`` over the simulated line (Verilator); returns the
    summary the test wrote (``out/summary.json``; ``out/link.json``: the link's figures). The
    build folder: ``build_name``, by default SystemLinkTop's, or with ``--ga hardware`` one per
    engine (:func:`learner_build_name`)."""
    from cosim.cocotb_run import REPO_ROOT, run_cocotb

    baud = sim_baud_default() if baud is None else float(baud)
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)
    hardware = config.ga == "hardware"
    if build_name is None:
        from cosim.learning_phase import hardware_ga_config

        build_name = (learner_build_name(hardware_ga_config(config), config.distance_rule, baud)
                      if hardware else TOPLEVEL)
    source, env = prepare_uart_run(config, out, baud=baud, p_max=p_max, build_name=build_name,
                                   resume=resume, plots=plots, progress=progress)
    run_cocotb(sources=[source], toplevel=LEARNER_TOPLEVEL if hardware else TOPLEVEL,
               test_module="cosim.uart_backend", test_dir=REPO_ROOT, build_name=build_name,
               testcase="online_experiment_uart", extra_env=env, simulator="verilator", waves=waves)
    return json.loads((out / "summary.json").read_text())


def launch(config, args) -> int:
    """``ehw sim --backend uart ...``: launch the simulation, print its summary and the link's figures."""
    from cosim.online_report import summary_table

    baud = sim_baud_default()
    top = "LearnerLinkTop" if config.ga == "hardware" else "SystemLinkTop"
    print(f"uart backend: {top} in Verilator at {SIM_CLK_HZ / 1e6:g} MHz, {baud:,.0f} baud")
    summary = run_online_uart(config, args.out, baud=baud, resume=args.resume,
                              plots=not args.no_plots, progress=not args.no_progress)
    from cosim.link_boards import link_lines

    print(summary_table(summary))
    print("\n".join(link_lines(json.loads((Path(args.out) / "link.json").read_text()))))
    print(f"wrote {Path(args.out) / 'summary.json'}")
    return 0
