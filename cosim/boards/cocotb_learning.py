"""The ``cocotb`` learning board: the learning engine's generated Verilog under cocotb (``--ga hardware``).

    make sim BACKEND=cocotb ARGS="--ga hardware"      (Verilator; SIM=icarus for Icarus)

As the cocotb board backend (``cosim.boards.cocotb_backend``), the whole lifetime runs inside a cocotb
test (``cosim.launch.cocotb_test``), but on ``learning_system_top`` (``hdl.learning_system_top``): the
system top's controller EHW drives the robot (``HDLControllerBoard``, unchanged), and the learning
board is the engine (``hdl.learner.Learner``, ports ``lrn_*``) driven by the same
``LearnerHost`` as the Amaranth learning board (``cosim.boards.amaranth_learning.HDLLearningBoard``):
observations (2 cycles each), failure-rate codes (1 cycle each), ``learn`` (one wait for
``done``: no Python while the engine runs), the download read back (50 cycles). Every learn is
checked against the reference learning board (download, counts, fail count, cycles).

The engine's parameters (population, tournament, lanes, rates) are constants of the circuit: the
launcher (``cosim.launch.cocotb_sim``) writes the Verilog for the run's parameters, builds it under a
name made from them (one build per configuration, kept between runs) and passes them in
``EHW_LEARNER_CONFIG``, which the board checks.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from base import environ
from cosim.boards.amaranth_learning import HDLLearningBoard
from cosim.boards.cocotb_backend import active_system
from ga.motions import DEFAULT_DISTANCE_RULE

TOPLEVEL = "learning_system_top"
CONFIG_ENV = "EHW_LEARNER_CONFIG"  # the HardwareGAConfig (JSON) of the Verilog under test


def build_name(ga_config, distance_rule: str = DEFAULT_DISTANCE_RULE) -> str:
    """The build folder's name for the engine of ``ga_config``: one build per circuit."""
    key = json.dumps({"config": ga_config.to_dict(), "rule": distance_rule}, sort_keys=True)
    return f"{TOPLEVEL}_{hashlib.sha256(key.encode()).hexdigest()[:10]}"


def write_learning_verilog(out_dir: Path | str, ga_config, distance_rule: str = DEFAULT_DISTANCE_RULE) -> Path:
    """``learning_system_top.v`` (the system top + the engine for ``ga_config``) in ``out_dir``."""
    from amaranth.back import verilog

    from cosim.boards.cocotb_run import icarus_time_zero_fix
    from hdl.learning_system_top import LearningSystemTop

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{TOPLEVEL}.v"
    top = LearningSystemTop(ga_config, distance_rule=distance_rule)
    text = icarus_time_zero_fix(verilog.convert(top, name=TOPLEVEL, emit_src=False))
    if not path.exists() or path.read_text() != text:  # an unchanged file keeps the build's stamp
        path.write_text(text)
    return path


def zero_learner_inputs(dut) -> None:
    """Drive every engine input of the top to 0 before reset (Icarus leaves them at z)."""
    from hdl.learning_system_top import LEARNER_INPUTS, PREFIX

    for name in LEARNER_INPUTS:
        getattr(dut, PREFIX + name).value = 0


def make_cocotb_learning_board(config, seed: int, population, reflex: bool = True,
                               distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """The learning board on the running test's ``learning_system_top`` (inside the simulator)."""
    from ga.hardware_ga import HardwareGAConfig
    from hdl.learning_system_top import LearnerHost

    system = active_system()
    built = environ.read(CONFIG_ENV)
    if built is None or HardwareGAConfig(**built) != config:
        raise RuntimeError(f"the Verilog under test is the engine for {built}, the run asks for "
                           f"{config.to_dict()}: launch it with cosim.launch.cocotb_sim.run_online_cocotb")
    return HDLLearningBoard(system.call, LearnerHost(system.pins), config, seed, population, reflex,
                            distance_rule, check)
