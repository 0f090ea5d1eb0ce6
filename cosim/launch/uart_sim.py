"""The ``uart`` board backend: the board top that goes into the bitstream, UART included
(``hdl.link_tops.SystemLinkTop``), in Verilator through cocotb, reached by the host code of the
``serial`` backend (``cosim.link.host``, ``cosim.link.boards``) over a simulated serial line.

    make sim BACKEND=uart [BAUD=...] ARGS="--targets 4 --population 20"
    make sim BACKEND=uart ARGS="--ga hardware --targets 2 --population 6 --lanes 2"

With ``--ga hardware`` the top is ``hdl.learner_link.LearnerLinkTop`` (the ``ulx3s-learner``
bitstream's: the controller board beside the learning engine, built for the run's population,
tournament, lanes and rates) and the boards are ``cosim.link.learning``'s, over the same line.

The launching process writes ``system_link_top.v``, builds it in Verilator and runs this module's
cocotb test :func:`online_experiment_uart`. Inside the simulator: the clock (``SIM_CLK_HZ``), a
reset, cocotbext-uart's ``UartSource`` on the top's ``rx`` pin and ``UartSink`` on its ``tx``
pin, and the experiment loop of ``cosim.online.run`` in a thread (``cocotb.task.bridge``). The loop's
boards are ``cosim.link.boards``' over a ``cosim.link.simulated.SimulatedSerial``: pyserial's ``write`` /
``read`` / ``reset_input_buffer``, each a coroutine run in the simulator (``cocotb.task.resume``),
with the read timeout in *simulated* seconds. Only the stream differs from a real board.

The default baud here is the fastest the simulated clock allows (``hdl.uart.max_baud``: a run's
bytes cost simulated cycles, and every cycle costs wall time); ``BAUD=115200`` gives the real
link's timing (``cosim.link_bench`` measures it).
"""

from __future__ import annotations

import json
from pathlib import Path

from base import environ
from cosim.launch.lifetime import launch_env, prepare_out, print_summary, run_in_simulator
from cosim.link.simulated import (
    LEARNER_TOPLEVEL,
    LINE_ENV,
    SIM_CLK_HZ,
    TOPLEVEL,
    board_timeout_s,
    host_timeout_s,
)
from ga.motions import DEFAULT_DISTANCE_RULE

BAUD_ENV = "EHW_BAUD"


def sim_baud_default() -> float:
    """``EHW_BAUD`` or the fastest baud of the simulated clock."""
    from hdl.uart import max_baud

    return environ.read(BAUD_ENV) or float(max_baud(SIM_CLK_HZ))


def write_link_verilog(out_dir: Path, *, baud: float, p_max: int | None = None,
                       distance_rule: str = DEFAULT_DISTANCE_RULE, ga_config=None) -> Path:
    """``system_link_top.v``: :class:`LinkHarness` around SystemLinkTop at ``SIM_CLK_HZ`` and
    ``baud`` (build id 0: the simulated top does not depend on the commit); with ``ga_config``
    (``--ga hardware``) ``learner_link_top.v`` around LearnerLinkTop for that engine."""
    from amaranth.back import verilog

    from cosim.boards.cocotb_run import icarus_time_zero_fix
    from hdl.link_harness import LinkHarness

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
    from cosim.boards.cocotb_run import SIM_BUILD
    from hdl.system_top import P_MAX

    line = environ.read(LINE_ENV, "hdl")
    env = {}
    if config.ga == "hardware":
        from cosim.online.learning_phase import hardware_ga_config
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
    return source, {**env, **launch_env(config, options)}


def run_online_uart(config, out: Path | str, *, baud: float | None = None, resume: bool = False,
                    plots: bool = False, progress: bool = False, build_name: str | None = None,
                    p_max: int | None = None, waves: bool | None = None) -> dict:
    """Run the on-line experiment ``config`` over the simulated line (Verilator); returns the
    summary the test wrote (``out/summary.json``; ``out/link.json``: the link's figures). The
    build folder: ``build_name``, by default SystemLinkTop's, or with ``--ga hardware`` one per
    engine (:func:`learner_build_name`)."""
    baud = sim_baud_default() if baud is None else float(baud)
    out = prepare_out(out)
    hardware = config.ga == "hardware"
    if build_name is None:
        from cosim.online.learning_phase import hardware_ga_config

        build_name = (learner_build_name(hardware_ga_config(config), config.distance_rule, baud)
                      if hardware else TOPLEVEL)
    source, env = prepare_uart_run(config, out, baud=baud, p_max=p_max, build_name=build_name,
                                   resume=resume, plots=plots, progress=progress)
    return run_in_simulator(out, sources=[source], toplevel=LEARNER_TOPLEVEL if hardware else TOPLEVEL,
                            test_module="cosim.launch.uart_test", build_name=build_name,
                            testcase="online_experiment_uart", extra_env=env, simulator="verilator",
                            waves=waves)


def launch(config, args) -> int:
    """``ehw sim --backend uart ...``: launch the simulation, print its summary and the link's figures."""
    from cosim.link.boards import link_lines

    baud = sim_baud_default()
    top = "LearnerLinkTop" if config.ga == "hardware" else "SystemLinkTop"
    print(f"uart backend: {top} in Verilator at {SIM_CLK_HZ / 1e6:g} MHz, {baud:,.0f} baud")
    summary = run_online_uart(config, args.out, baud=baud, resume=args.resume,
                              plots=not args.no_plots, progress=not args.no_progress)
    print_summary(summary, args.out, link_lines(json.loads((Path(args.out) / "link.json").read_text())))
    return 0
