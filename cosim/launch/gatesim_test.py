"""The cocotb test module of ``ehw gatesim``: a synthesised board top driven by the host code.

``cosim.launch.gatesim`` builds the harness around the netlist(s) (``hdl.gatesim``) and runs one
of these tests with its options in the environment (``cosim.launch.lifetime``). The line to each
board is ``cosim.link.simulated.HarnessSerial``: the harness's own UART at the board's baud sends
and receives bit by bit on the netlist's UART pins. The host code is the ``serial`` backend's,
unchanged (``cosim.link.host.LinkClient``, ``cosim.link.boards``), with the NumPy reference beside
every board (``check``): the first motion or count that differs raises ``LinkMismatch``.

- :func:`gate_motions`: the controller board alone: IDENTIFY, SET_REFLEX, then per genome
  LOAD_CONTROLLER and MOTION in every state of a seeded sample (a few hundred bytes).
- :func:`gate_lifetime`: an on-line lifetime on the boards (one system board, the controller
  and the evaluator iCEBreakers side by side, or with ``--ga hardware`` one learner board);
  writes ``summary.json``, ``motions.json`` (the motions executed) and ``link.json``.

Only cocotb imports this module.
"""

from __future__ import annotations

import json
from pathlib import Path

import cocotb

from cosim.launch.lifetime import read_launch_env
from cosim.link import simulated

# Cycles from the harness's reset to the first byte: the board's power-on reset (iCE40: 15 us)
# and the evaluator's RAM sweep (2,049 cycles), with margin.
BOOT_CYCLES = 6000


class _Side:
    """One board's signals of a ``PairHarness`` (``controller_internal``, ...) under the names of
    a single ``LinkHarness``, for ``HarnessSerial``."""

    def __init__(self, dut, role: str):
        self._dut, self._role = dut, role

    def __getattr__(self, name):
        return getattr(self._dut, name if name == "clk" else f"{self._role}_{name}")


async def _start(dut, options) -> list:
    """Clock and reset the harness, wait for the boards to boot; one line per board role."""
    from cocotb.clock import Clock
    from cocotb.triggers import ClockCycles

    roles = options["roles"]
    sides = [dut] if len(roles) == 1 else [_Side(dut, role) for role in roles]
    for side in sides:
        side.rx.value = 1
        side.internal.value = 1
        side.host_w_en.value = 0
    Clock(dut.clk, 2 * round(0.5e12 / options["clk_freq_hz"]), unit="ps", impl="gpi").start(start_high=False)
    dut.rst.value = 1
    await ClockCycles(dut.clk, 2)
    dut.rst.value = 0
    await ClockCycles(dut.clk, BOOT_CYCLES)
    return [simulated.HarnessSerial(side, options["host_timeout_s"], f"{options['target']} ({role}, gate level)")
            for side, role in zip(sides, roles)]


def _write(out: Path, name: str, value) -> None:
    (out / name).write_text(json.dumps(value, indent=1) + "\n")


async def _reporting(out: Path, job) -> None:
    """Run ``job`` in the bridge thread; its exception (a ``LinkMismatch``: what differed) also
    goes to ``out/error.json`` for the launcher's results."""
    from cocotb.task import bridge

    try:
        await bridge(job)()
    except Exception as exc:
        _write(out, "error.json", {"error": f"{type(exc).__name__}: {exc}"})
        raise


@cocotb.test()
async def gate_motions(dut):
    """The controller board's netlist (or the learner board's): genomes loaded over the link,
    motions == the reference."""
    _, options = read_launch_env()
    (line,) = await _start(dut, options)
    out = Path(options["out"])

    def check() -> dict:
        import numpy as np

        from cosim.link.boards import LinkControllerBoard
        from cosim.link.host import LinkClient
        from ga.genome import N_ROWS, ROW_BITS
        from ga.motions import N_STATES
        from hdl.link_protocol import Design

        client = LinkClient(line)
        # the learner board decodes the controller board's commands too (hdl.link_protocol)
        identity = client.expect(Design.LEARNER if options["target"] == "ulx3s-learner" else Design.CONTROLLER)
        rng = np.random.default_rng(options["seed"])
        board = LinkControllerBoard(client, reflex=True, check=True)  # SET_REFLEX
        motions = []
        for g in range(options["genomes"]):
            board.load(rng.integers(0, 1 << ROW_BITS, size=N_ROWS, dtype=np.uint32))
            if g % 2:
                board.set_reflex(False)
            for state in rng.choice(N_STATES, size=options["states"], replace=False):
                motions.append(board.motion(int(state)))  # LinkMismatch if it differs
            board.set_reflex(True)
        return {"design": identity.design, "interactions": len(motions), "motions": motions,
                "bytes_sent": client.stats.bytes_sent, "bytes_received": client.stats.bytes_received,
                "requests": client.stats.requests, "resends": client.stats.resends}

    await _reporting(out, lambda: _write(out, "motions.json", check()))


@cocotb.test()
async def gate_lifetime(dut):
    """An on-line lifetime on the boards' netlists; options from the environment."""
    config, options = read_launch_env()
    lines = await _start(dut, options)
    out = Path(options["out"])

    def lifetime() -> None:
        from cosim.link.boards import boards_over, write_link_summary
        from cosim.link.host import LinkClient
        from cosim.online.config import OnlineConfig
        from cosim.online.report import write_results
        from cosim.online.run import OnlineRun

        cfg = OnlineConfig(**config)
        if cfg.ga == "hardware":  # the learner board: the uart backend's own boards, over this line
            from cosim.online.run import make_run

            (line,) = lines
            simulated.activate(line)
            try:
                run = make_run(cfg, "uart", progress=bool(options.get("progress")))
                run.run()
            finally:
                simulated.activate(None)
        else:
            controller, evaluator = boards_over([LinkClient(line) for line in lines], reflex=cfg.reflex,
                                                check=True, distance_rule=cfg.distance_rule)
            run = OnlineRun(cfg, controller, evaluator, checkpoint=None,
                            progress=bool(options.get("progress")), backend="uart")
            run.run()
        write_results(run, out, plots=False)
        _write(out, "motions.json", {"interactions": run.interactions, "motions": list(run.motions)})
        write_link_summary(run, out)

    await _reporting(out, lifetime)
