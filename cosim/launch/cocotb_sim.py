"""The launcher of the cocotb backend: build the system top's Verilog and run the lifetime in it.

    ehw sim --backend cocotb [--simulator verilator|icarus] --seed 1   (make sim BACKEND=cocotb [SIM=icarus] [WAVES=1])

The process of ``ehw sim`` only launches the simulation
(:func:`run_online_cocotb`): it writes ``system_top.v`` (``hdl.system_top.SystemTop``: controller
EHW + evaluator EHW + population streamer), builds it with Icarus or Verilator (``EHW_SIM``)
through ``cosim.boards.cocotb_run.run_cocotb`` and runs the cocotb test of ``cosim.launch.cocotb_test``,
which writes ``summary.json`` (with ``--ga hardware`` the top is ``learning_system_top``, the
engine built for the run's parameters: ``cosim.boards.cocotb_learning``); this process reads it and prints
the same table as the other backends. On Verilator the system top's toplevel is
``system_top_clocked`` (:func:`clocked_top_verilog`: the clock generated in the Verilog, built with
``--timing``), 2x faster than cocotb's GPI clock; the learning top keeps cocotb's clock.
``WAVES=1`` dumps the simulation next to the build.
"""

from __future__ import annotations

import json
from pathlib import Path

from base import environ
from cosim.boards.amaranth_backend import SAMPLE_ENV
from cosim.boards.cocotb_backend import CLOCK_INSIDE_ENV, CLOCK_PERIOD_NS
from cosim.boards.cocotb_run import SIM_BUILD, icarus_time_zero_fix, simulator_default
from cosim.boards.hardware_time import hardware_line
from cosim.launch.lifetime import launch_env, prepare_out, print_summary, run_in_simulator
from ga.motions import DEFAULT_DISTANCE_RULE

TOPLEVEL = "system_top"
CLOCKED_TOPLEVEL = "system_top_clocked"  # TOPLEVEL with its clock generated inside (Verilator runs)


def clocked_top_verilog(top, core: str = TOPLEVEL, name: str = CLOCKED_TOPLEVEL,
                        period_ns: int = CLOCK_PERIOD_NS) -> str:
    """A Verilog module ``name`` that holds module ``core`` (the Verilog of the Amaranth component
    ``top``, which has ``clk`` and ``rst``) with every port but ``clk`` brought out, and the clock
    generated inside: ``always #(period/2) clk = ~clk`` from 0 at time 0 (falling edges at
    multiples of the period, as cocotb's clock started low). In Verilator (``--timing``) this
    saves cocotb's GPI clock, a VPI write of the top's clk input at every half period and the
    input-combinational settle it triggers (docs/hdl_in_the_loop.md)."""
    from amaranth.hdl import Value
    from amaranth.lib import wiring

    if period_ns % 2:
        raise ValueError(f"period_ns must be even (a whole half period), got {period_ns!r}")
    ports = [("rst", 1, "input")]
    for path, member, value in top.signature.flatten(top):
        ports.append(("__".join(map(str, path)), len(Value.cast(value)),
                      "input" if member.flow == wiring.In else "output"))
    decls = [f"  {direction} {f'[{width - 1}:0] ' if width > 1 else ''}{port};" for port, width, direction in ports]
    conns = ",\n".join(f"    .{port}({port})" for port, _, _ in [("clk", 1, "")] + ports)
    return (f"module {name}({', '.join(port for port, _, _ in ports)});\n" + "\n".join(decls)
            + f"\n  reg clk = 1'b0;\n  always #{period_ns // 2} clk = ~clk;\n"
            + f"  {core} core (\n{conns}\n  );\nendmodule\n")


def write_system_verilog(out_dir: Path | str | None = None, p_max: int | None = None,
                         distance_rule: str = DEFAULT_DISTANCE_RULE, clock_inside: bool = False) -> Path:
    """``system_top.v`` (regenerated each time: a few seconds); ``p_max`` other than the default
    gives a smaller population RAM (tests: set ``EHW_SYSTEM_P_MAX`` to match). ``clock_inside``:
    the file also holds :func:`clocked_top_verilog`'s ``system_top_clocked`` (the toplevel of a
    run with ``EHW_CLOCK_INSIDE=1``)."""
    from amaranth.back import verilog

    from hdl.system_top import P_MAX, SystemTop

    out = Path(out_dir) if out_dir else SIM_BUILD / "verilog"
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{TOPLEVEL}.v"
    top = SystemTop(p_max=P_MAX if p_max is None else p_max, distance_rule=distance_rule)
    text = icarus_time_zero_fix(verilog.convert(top, name=TOPLEVEL, emit_src=False))
    if clock_inside:
        text += "\n" + clocked_top_verilog(top)
    path.write_text(text)
    return path


def run_online_cocotb(config, out: Path | str, *, resume: bool = False, plots: bool = False,
                      progress: bool = False, waves: bool | None = None, clock_hz: float | None = None,
                      sample: int | None = None, build_name: str = TOPLEVEL,
                      simulator: str | None = None) -> dict:
    """Run the on-line experiment ``config`` (a ``cosim.online.run.OnlineConfig``) inside a cocotb
    test on the Verilog boards; returns the summary the test wrote to ``out/summary.json``.
    ``sample``: HDL-evaluate only that many controllers per population (spot-check mode; default
    ``EHW_HDL_SAMPLE`` or all). ``simulator``: ``icarus`` or ``verilator`` (default ``EHW_SIM``
    or Icarus; see ``cosim.boards.cocotb_run``)."""
    simulator = simulator or simulator_default()
    clock_inside = simulator == "verilator"  # its own clock: one eval a half period, no VPI clock
    out = prepare_out(out)
    rule = config.distance_rule
    if rule != DEFAULT_DISTANCE_RULE and build_name == TOPLEVEL:
        build_name = f"{TOPLEVEL}_{rule}"  # other Verilog: its own build
    options = {"out": str(out), "resume": resume, "plots": plots, "progress": progress}
    toplevel = TOPLEVEL
    if config.ga == "hardware":  # the learning engine beside the controller (cosim.boards.cocotb_learning)
        from cosim.boards import cocotb_learning
        from cosim.online.learning_phase import hardware_ga_config

        clock_inside = False  # the learning top has no clocked wrapper: cocotb's GPI clock
        ga_config = hardware_ga_config(config)
        toplevel, build_name = cocotb_learning.TOPLEVEL, cocotb_learning.build_name(ga_config, rule)
        source = cocotb_learning.write_learning_verilog(SIM_BUILD / f"{build_name}_verilog", ga_config, rule)
    else:  # one folder per build: runs may overlap
        source = write_system_verilog(SIM_BUILD / f"{build_name}_verilog", distance_rule=rule,
                                      clock_inside=clock_inside)
        if clock_inside:
            toplevel = CLOCKED_TOPLEVEL
    env = {**launch_env(config, options), CLOCK_INSIDE_ENV: str(int(clock_inside))}
    if config.ga == "hardware":
        env[cocotb_learning.CONFIG_ENV] = json.dumps(ga_config.to_dict())
    if clock_hz is not None:  # else the run in the simulator finds the measured clock itself
        env["EHW_CLOCK_HZ"] = str(clock_hz)
    if sample is not None:  # spot-check mode (cosim.boards.amaranth_backend.HDLEvaluatorBoard)
        env[SAMPLE_ENV] = str(int(sample))
    return run_in_simulator(
        out, sources=[source], toplevel=toplevel, test_module="cosim.launch.cocotb_test",
        build_name=build_name, testcase="online_experiment", waves=waves, extra_env=env,
        simulator=simulator, timing=clock_inside,
    )


def launch(config, args) -> int:
    """``ehw sim --backend cocotb ...``: launch the simulation, print its summary."""
    simulator = simulator_default()
    print(f"cocotb backend on {simulator} ({'EHW_SIM' if environ.raw('EHW_SIM') else 'default'})")
    summary = run_online_cocotb(config, args.out, resume=args.resume, plots=not args.no_plots,
                                progress=not args.no_progress, simulator=simulator)
    from cosim.online.report import summary_table

    extra = [hardware_line(summary)] if "hardware" in summary and "evaluator EHW" not in summary_table(summary) else []
    print_summary(summary, args.out, extra)
    return 0
