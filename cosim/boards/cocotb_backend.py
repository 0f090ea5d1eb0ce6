"""The ``cocotb`` board backend: both EHW boards on the generated Verilog of ``hdl.system_top``
in Icarus Verilog or Verilator, driven from inside a cocotb test (SPEC section 9).

Three modules, one job each:

- this one, the backend: :class:`CocotbSystem` (``hdl.ports.CocotbPins`` over the top's
  handles; clock, reset, RAM sweep; ``call(job, *args)`` runs a ``SystemHost``
  coroutine from the experiment's thread with ``cocotb.task.resume``) and the board factory
  registered as ``cocotb`` (the boards of ``cosim.boards.amaranth_backend`` over this system);
- ``cosim.launch.cocotb_test``, the cocotb test module: its test starts the system and runs the
  lifetime of ``cosim.online.run`` in a thread (``cocotb.task.bridge``);
- ``cosim.launch.cocotb_sim``, the launcher: writes and builds ``system_top.v`` and runs that test
  (``make sim BACKEND=cocotb [SIM=icarus] [WAVES=1]``).

Each board call is a coroutine of ``hdl.system_top.SystemHost`` run in the simulator:

- ``controller.load(rows)``: 50 row writes into the controller EHW's shadow, commit with the last;
- ``controller.motion(s)``: the sensor bits for one cycle, the registered motion read back;
- ``evaluator.observe(...)``: the resulting world-model entry and both states written (2 cycles);
- ``evaluator.write_rates(changes)``: failure-rate codes (``ga.fail_rates``), one a cycle;
- ``evaluator.evaluate(pop)``: the population written into the streamer's RAM (one genome per
  cycle), one ``go``, then *one* wait for ``pop_done`` (no Python while the evaluator works:
  the streamer loads each controller's rows into the evaluator and starts it, overlapped with the
  previous evaluation), then the results read back.
"""

from __future__ import annotations


from base import environ
from cosim.boards.amaranth_backend import BoardLog, HDLControllerBoard, HDLEvaluatorBoard
from cosim.boards.registry import register_backend
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.ports import CocotbPins

P_MAX_ENV = "EHW_SYSTEM_P_MAX"  # the population RAM depth of the Verilog under test
CLOCK_PERIOD_NS = 10  # simulated clock; the hardware time uses the FPGA clock (EHW_CLOCK_HZ)
# "1": the toplevel generates its own clock (cosim.launch.cocotb_sim.clocked_top_verilog), so the
# test starts none; else cocotb's GPI clock drives the top's clk input
CLOCK_INSIDE_ENV = "EHW_CLOCK_INSIDE"

_active_system = None  # the CocotbSystem of the running test (inside the simulator only): activate()


class CocotbSystem:
    """The system top under cocotb: ``call(job, *args)`` runs a ``SystemHost`` coroutine from the
    experiment's thread (``cocotb.task.resume``)."""

    def __init__(self, dut, p_max: int | None = None, clock_inside: bool | None = None):
        from hdl.system_top import P_MAX, SystemHost

        self.dut = dut
        if clock_inside is None:
            clock_inside = environ.read(CLOCK_INSIDE_ENV, False)
        self.clock_inside = clock_inside
        self.pins = CocotbPins(dut)
        self.host = SystemHost(self.pins, p_max=p_max or environ.read(P_MAX_ENV, P_MAX))

    async def start(self) -> None:
        """Clock (unless the top has its own), synchronous reset, then the evaluator's RAM sweep
        (Boot + Clear)."""
        from cocotb.clock import Clock

        if not self.clock_inside:
            Clock(self.dut.clk, CLOCK_PERIOD_NS, unit="ns", impl="gpi").start(start_high=False)
        self.dut.rst.value = 1
        # GPI clock: the first falling edge is the clock's start (no rising edge yet); a clock
        # inside the top falls first at 10 ns: one more edge in reset, which changes nothing
        await self.pins.tick()
        await self.pins.tick()
        self.dut.rst.value = 0
        await self.host.boot()

    def call(self, job, *args):
        from cocotb.task import resume

        return resume(job)(*args)


def make_cocotb_boards(reflex: bool = True, check: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE):
    """The board pair on the running test's system top (inside the simulator only)."""
    system = active_system()
    system.call(system.host.reflex, bool(reflex))
    log = BoardLog()
    return (HDLControllerBoard(system, reflex, check, log=log),
            HDLEvaluatorBoard(system, reflex, check, log=log, distance_rule=distance_rule))


def active_system() -> CocotbSystem:
    """The running test's system (inside the simulator only)."""
    if _active_system is None:
        raise RuntimeError(
            "the cocotb backend runs the experiment inside the simulator: start it with "
            "`ehw sim --backend cocotb` or cosim.launch.cocotb_sim.run_online_cocotb(config, out)"
        )
    return _active_system


def activate(system: CocotbSystem | None) -> None:
    """Make ``system`` the one the boards are made on (None: the test has ended)."""
    global _active_system
    _active_system = system


register_backend("cocotb", make_cocotb_boards)
