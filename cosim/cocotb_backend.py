"""The ``cocotb`` board backend: the on-line experiment runs inside a cocotb test, on the generated
Verilog of both EHW boards in Icarus Verilog or Verilator (``EHW_SIM``, see ``cosim.cocotb_run``).

    EHW_SIM=verilator python -m cosim.online --backend cocotb --seed 1   (make sim BACKEND=cocotb [SIM=icarus] [WAVES=1])

The process that is started (``python -m cosim.online``) only launches the simulation
(:func:`run_online_cocotb`): it writes ``system_top.v`` (``hdl.system_top.SystemTop``: controller
EHW + evaluator EHW + population streamer), builds it with Icarus (or Verilator: ``EHW_SIM``,
``make sim BACKEND=cocotb SIM=verilator``) through ``cosim.cocotb_run.run_cocotb`` and runs this module's cocotb test :func:`online_experiment`,
passing the run's configuration and options in environment variables (``EHW_ONLINE_CONFIG``,
``EHW_ONLINE_OPTIONS``, JSON). Inside the simulator the test starts the clock, resets the top, waits
for the evaluator's RAM sweep, and runs the whole experiment loop of ``cosim.online`` in a thread
(``cocotb.task.bridge``): the loop steps the pymunk world and calls the boards, and each board call
is a coroutine of ``hdl.system_top.SystemHost`` run in the simulator (``cocotb.task.resume``):

- ``controller.load(rows)``: 50 row writes into the controller EHW's shadow, commit with the last;
- ``controller.motion(s)``: the sensor bits for one cycle, the registered motion read back;
- ``evaluator.observe(...)``: the resulting world-model entry and both states written (2 cycles);
- ``evaluator.evaluate(pop)``: the population written into the streamer's RAM (one genome per
  cycle), one ``go``, then *one* wait for ``pop_done`` (no Python while the evaluator works:
  the streamer loads each controller's rows into the evaluator and starts it, overlapped with the
  previous evaluation), then the results read back.

The test writes ``summary.json`` (plus ``board_log.json``: executed motions, downloaded genomes,
a digest of every evaluation) into the output folder; the launching process reads it and prints
the same table as the other backends. ``WAVES=1`` dumps ``build/sim/system_top/system_top.fst``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from cosim.amaranth_backend import SAMPLE_ENV, BoardLog, HDLControllerBoard, HDLEvaluatorBoard
from cosim.hardware_time import hardware_line
from cosim.boards import register_backend
from hdl.ports import CocotbPins

TOPLEVEL = "system_top"
CONFIG_ENV = "EHW_ONLINE_CONFIG"
OPTIONS_ENV = "EHW_ONLINE_OPTIONS"
P_MAX_ENV = "EHW_SYSTEM_P_MAX"  # the population RAM depth of the Verilog under test
CLOCK_PERIOD_NS = 10  # simulated clock; the hardware time uses the FPGA clock (EHW_CLOCK_HZ)

_active_system = None  # the CocotbSystem of the running test (inside the simulator only)


class CocotbSystem:
    """The system top under cocotb: ``call(job, *args)`` runs a ``SystemHost`` coroutine from the
    experiment's thread (``cocotb.task.resume``)."""

    def __init__(self, dut, p_max: int | None = None):
        from hdl.system_top import P_MAX, SystemHost

        self.dut = dut
        self.pins = CocotbPins(dut)
        self.host = SystemHost(self.pins, p_max=p_max or int(os.environ.get(P_MAX_ENV, P_MAX)))

    async def start(self) -> None:
        """Clock, synchronous reset, then the evaluator's RAM sweep (Boot + Clear)."""
        from cocotb.clock import Clock

        Clock(self.dut.clk, CLOCK_PERIOD_NS, unit="ns", impl="gpi").start(start_high=False)
        self.dut.rst.value = 1
        await self.pins.tick()  # the first falling edge is the clock's start: no rising edge yet
        await self.pins.tick()
        self.dut.rst.value = 0
        await self.host.boot()

    def call(self, job, *args):
        from cocotb.task import resume

        return resume(job)(*args)


def make_cocotb_boards(reflex: bool = True, check: bool = True, distance_rule: str = "covered"):
    """The board pair on the running test's system top (inside the simulator only)."""
    if _active_system is None:
        raise RuntimeError(
            "the cocotb backend runs the experiment inside the simulator: start it with "
            "`python -m cosim.online --backend cocotb` or cosim.cocotb_backend.run_online_cocotb(config)"
        )
    _active_system.call(_active_system.host.reflex, bool(reflex))
    log = BoardLog()
    return (HDLControllerBoard(_active_system, reflex, check, log=log),
            HDLEvaluatorBoard(_active_system, reflex, check, log=log, distance_rule=distance_rule))


register_backend("cocotb", make_cocotb_boards)


# -- inside the simulator ---------------------------------------------------------------------------

try:
    import cocotb
except ImportError:  # pragma: no cover - cocotb is a dependency; keep the module importable anyway
    cocotb = None


def _experiment(config: dict, options: dict) -> dict:
    """The blocking experiment (runs in cocotb's bridge thread)."""
    from cosim.online import OnlineConfig, make_run, write_results

    cfg = OnlineConfig(**config)
    out = Path(options["out"])
    run = make_run(cfg, "cocotb", out if options.get("checkpoint", True) else None,
                   resume=bool(options.get("resume")), progress=bool(options.get("progress")))
    run.run()
    summary = write_results(run, out, plots=bool(options.get("plots")))
    run.controller.log.write(out / "board_log.json", run.motions)
    return summary


if cocotb is not None:

    @cocotb.test()
    async def online_experiment(dut):
        """The whole on-line experiment on system_top; options from the environment."""
        global _active_system
        from cocotb.task import bridge

        config = json.loads(os.environ[CONFIG_ENV])
        options = json.loads(os.environ[OPTIONS_ENV])
        system = CocotbSystem(dut)
        await system.start()
        _active_system = system
        try:
            await bridge(_experiment)(config, options)
        finally:
            _active_system = None


# -- the launching process --------------------------------------------------------------------------


def icarus_time_zero_fix(verilog: str) -> str:
    """The time-0 fix every generated Verilog file gets (``hdl.generate.time_zero_fix``)."""
    from hdl.generate import time_zero_fix

    return time_zero_fix(verilog)


def write_system_verilog(out_dir: Path | str | None = None, p_max: int | None = None,
                         distance_rule: str = "covered") -> Path:
    """``system_top.v`` for Icarus (regenerated each time: a few seconds); ``p_max`` other than
    the default gives a smaller population RAM (tests: set ``EHW_SYSTEM_P_MAX`` to match)."""
    from amaranth.back import verilog

    from cosim.cocotb_run import SIM_BUILD
    from hdl.system_top import P_MAX, SystemTop

    out = Path(out_dir) if out_dir else SIM_BUILD / "verilog"
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{TOPLEVEL}.v"
    top = SystemTop(p_max=P_MAX if p_max is None else p_max, distance_rule=distance_rule)
    path.write_text(icarus_time_zero_fix(verilog.convert(top, name=TOPLEVEL, emit_src=False)))
    return path


def run_online_cocotb(config, out: Path | str, *, resume: bool = False, plots: bool = False,
                      progress: bool = False, waves: bool | None = None, clock_hz: float | None = None,
                      sample: int | None = None, build_name: str = TOPLEVEL,
                      simulator: str | None = None) -> dict:
    """Run the on-line experiment ``config`` (a ``cosim.online.OnlineConfig``) inside a cocotb
    test on the Verilog boards; returns the summary the test wrote to ``out/summary.json``.
    ``sample``: HDL-evaluate only that many controllers per population (spot-check mode; default
    ``EHW_HDL_SAMPLE`` or all). ``simulator``: ``icarus`` or ``verilator`` (default ``EHW_SIM``
    or Icarus; see ``cosim.cocotb_run``)."""
    from cosim.cocotb_run import REPO_ROOT, SIM_BUILD, run_cocotb

    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary_path.unlink(missing_ok=True)
    rule = config.distance_rule
    if rule != "covered" and build_name == TOPLEVEL:
        build_name = f"{TOPLEVEL}_{rule}"  # other Verilog: its own build
    # one folder per build: runs may overlap
    source = write_system_verilog(SIM_BUILD / f"{build_name}_verilog", distance_rule=rule)
    options = {"out": str(out), "resume": resume, "plots": plots, "progress": progress}
    env = {CONFIG_ENV: json.dumps(config.to_dict()), OPTIONS_ENV: json.dumps(options)}
    if clock_hz is not None:  # else the run in the simulator finds the measured clock itself
        env["EHW_CLOCK_HZ"] = str(clock_hz)
    if sample is not None:  # spot-check mode (cosim.amaranth_backend.HDLEvaluatorBoard)
        env[SAMPLE_ENV] = str(int(sample))
    run_cocotb(
        sources=[source], toplevel=TOPLEVEL, test_module="cosim.cocotb_backend", test_dir=REPO_ROOT,
        build_name=build_name, testcase="online_experiment", waves=waves,
        extra_env=env, simulator=simulator,
    )
    return json.loads(summary_path.read_text())


def main_from_args(args, config) -> int:
    """``python -m cosim.online --backend cocotb ...``: launch the simulation, print its summary."""
    from cosim.cocotb_run import simulator_default
    from cosim.online import summary_table

    simulator = simulator_default()
    print(f"cocotb backend on {simulator} ({'EHW_SIM' if os.environ.get('EHW_SIM') else 'default'})")
    summary = run_online_cocotb(config, args.out, resume=args.resume, plots=not args.no_plots,
                                progress=not args.no_progress, simulator=simulator)
    print(summary_table(summary))
    if "hardware" in summary and "evaluator EHW" not in summary_table(summary):
        print(hardware_line(summary))
    print(f"wrote {Path(args.out) / 'summary.json'}")
    return 0
