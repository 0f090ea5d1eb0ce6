"""The cocotb test module of the cocotb backend: the whole on-line lifetime inside the simulator.

``cosim.cocotb_launch`` builds ``system_top.v`` and runs :func:`online_experiment` with the run's
configuration and options in environment variables (``EHW_ONLINE_CONFIG``, ``EHW_ONLINE_OPTIONS``,
JSON). The test starts the clock, resets the top, waits for the evaluator's RAM sweep, and runs
the lifetime of ``cosim.online`` in a thread (``cocotb.task.bridge``) on the boards of
``cosim.cocotb_backend`` (with ``--ga hardware``: on ``learning_system_top``, whose engine is
the learning board of ``cosim.cocotb_learning``). It writes ``summary.json`` (plus ``board_log.json``: executed motions,
downloaded genomes, a digest of every evaluation) into the output folder.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cocotb

from cosim.cocotb_backend import CocotbSystem, activate

CONFIG_ENV = "EHW_ONLINE_CONFIG"
OPTIONS_ENV = "EHW_ONLINE_OPTIONS"


def _experiment(config: dict, options: dict) -> dict:
    """The blocking experiment (runs in cocotb's bridge thread)."""
    from cosim.online import OnlineConfig, make_run
    from cosim.online_report import write_results

    cfg = OnlineConfig(**config)
    out = Path(options["out"])
    run = make_run(cfg, "cocotb", out if options.get("checkpoint", True) else None,
                   resume=bool(options.get("resume")), progress=bool(options.get("progress")))
    run.run()
    summary = write_results(run, out, plots=bool(options.get("plots")))
    run.controller.log.write(out / "board_log.json", run.motions)
    return summary


@cocotb.test()
async def online_experiment(dut):
    """The whole on-line experiment on system_top (or learning_system_top); options from the environment."""
    from cocotb.task import bridge

    config = json.loads(os.environ[CONFIG_ENV])
    options = json.loads(os.environ[OPTIONS_ENV])
    system = CocotbSystem(dut)
    if config.get("ga") == "hardware":  # learning_system_top: the engine's inputs too
        from cosim.cocotb_learning import zero_learner_inputs

        zero_learner_inputs(dut)
    await system.start()
    activate(system)
    try:
        await bridge(_experiment)(config, options)
    finally:
        activate(None)
