"""The launcher of the cocotb backend: build the system top's Verilog and run the lifetime in it.

    EHW_SIM=verilator python -m cosim.online --backend cocotb --seed 1   (make sim BACKEND=cocotb [SIM=icarus] [WAVES=1])

The process that is started (``python -m cosim.online``) only launches the simulation
(:func:`run_online_cocotb`): it writes ``system_top.v`` (``hdl.system_top.SystemTop``: controller
EHW + evaluator EHW + population streamer), builds it with Icarus or Verilator (``EHW_SIM``)
through ``cosim.cocotb_run.run_cocotb`` and runs the cocotb test of ``cosim.cocotb_online``,
which writes ``summary.json`` (with ``--ga hardware`` the top is ``learning_system_top``, the
engine built for the run's parameters: ``cosim.cocotb_learning``); this process reads it and prints the same table as the other
backends. ``WAVES=1`` dumps the simulation next to the build.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from cosim.amaranth_backend import SAMPLE_ENV
from cosim.cocotb_online import CONFIG_ENV, OPTIONS_ENV
from cosim.cocotb_run import REPO_ROOT, SIM_BUILD, icarus_time_zero_fix, run_cocotb, simulator_default
from cosim.hardware_time import hardware_line
from ga.motions import DEFAULT_DISTANCE_RULE

TOPLEVEL = "system_top"


def write_system_verilog(out_dir: Path | str | None = None, p_max: int | None = None,
                         distance_rule: str = DEFAULT_DISTANCE_RULE) -> Path:
    """``system_top.v`` for Icarus (regenerated each time: a few seconds); ``p_max`` other than
    the default gives a smaller population RAM (tests: set ``EHW_SYSTEM_P_MAX`` to match)."""
    from amaranth.back import verilog

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
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary_path.unlink(missing_ok=True)
    rule = config.distance_rule
    if rule != DEFAULT_DISTANCE_RULE and build_name == TOPLEVEL:
        build_name = f"{TOPLEVEL}_{rule}"  # other Verilog: its own build
    options = {"out": str(out), "resume": resume, "plots": plots, "progress": progress}
    env = {CONFIG_ENV: json.dumps(config.to_dict()), OPTIONS_ENV: json.dumps(options)}
    toplevel = TOPLEVEL
    if config.ga == "hardware":  # the learning engine beside the controller (cosim.cocotb_learning)
        from cosim import cocotb_learning
        from cosim.learning_phase import hardware_ga_config

        ga_config = hardware_ga_config(config)
        toplevel, build_name = cocotb_learning.TOPLEVEL, cocotb_learning.build_name(ga_config, rule)
        source = cocotb_learning.write_learning_verilog(SIM_BUILD / f"{build_name}_verilog", ga_config, rule)
        env[cocotb_learning.CONFIG_ENV] = json.dumps(ga_config.to_dict())
    else:  # one folder per build: runs may overlap
        source = write_system_verilog(SIM_BUILD / f"{build_name}_verilog", distance_rule=rule)
    if clock_hz is not None:  # else the run in the simulator finds the measured clock itself
        env["EHW_CLOCK_HZ"] = str(clock_hz)
    if sample is not None:  # spot-check mode (cosim.amaranth_backend.HDLEvaluatorBoard)
        env[SAMPLE_ENV] = str(int(sample))
    run_cocotb(
        sources=[source], toplevel=toplevel, test_module="cosim.cocotb_online", test_dir=REPO_ROOT,
        build_name=build_name, testcase="online_experiment", waves=waves,
        extra_env=env, simulator=simulator,
    )
    return json.loads(summary_path.read_text())


def launch(config, args) -> int:
    """``python -m cosim.online --backend cocotb ...``: launch the simulation, print its summary."""
    from cosim.online_report import summary_table

    simulator = simulator_default()
    print(f"cocotb backend on {simulator} ({'EHW_SIM' if os.environ.get('EHW_SIM') else 'default'})")
    summary = run_online_cocotb(config, args.out, resume=args.resume, plots=not args.no_plots,
                                progress=not args.no_progress, simulator=simulator)
    table = summary_table(summary)
    print(table)
    if "hardware" in summary and "evaluator EHW" not in table:
        print(hardware_line(summary))
    print(f"wrote {Path(args.out) / 'summary.json'}")
    return 0
