"""The cocotb test module of the cocotb backend: the whole on-line lifetime inside the simulator.

``cosim.launch.cocotb_sim`` builds ``system_top.v`` and runs :func:`online_experiment` with the run's
configuration and options in the environment (``cosim.launch.lifetime``). The test starts the clock, resets the top, waits for the evaluator's RAM sweep, and runs
the lifetime of ``cosim.online.run`` in a thread (``cocotb.task.bridge``) on the boards of
``cosim.boards.cocotb_backend`` (with ``--ga hardware``: on ``learning_system_top``, whose engine is
the learning board of ``cosim.boards.cocotb_learning``). It writes ``summary.json`` (plus ``board_log.json``: executed motions,
downloaded genomes, a digest of every evaluation) into the output folder.
"""

from __future__ import annotations

import cocotb

from cosim.boards.cocotb_backend import CocotbSystem, activate
from cosim.launch.lifetime import lifetime_in_simulator, read_launch_env


@cocotb.test()
async def online_experiment(dut):
    """The whole on-line experiment on system_top (or learning_system_top); options from the environment."""
    from pathlib import Path

    from cocotb.task import bridge

    config, options = read_launch_env()
    system = CocotbSystem(dut)
    if config.get("ga") == "hardware":  # learning_system_top: the engine's inputs too
        from cosim.boards.cocotb_learning import zero_learner_inputs

        zero_learner_inputs(dut)
    await system.start()
    activate(system)
    try:
        run, _ = await bridge(lifetime_in_simulator)(config, options, "cocotb",
                                                     checkpoint=options.get("checkpoint", True))
        run.controller.log.write(Path(options["out"]) / "board_log.json", run.motions)
    finally:
        activate(None)
