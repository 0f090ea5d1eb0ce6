"""What the two simulator launchers share: a lifetime run inside a cocotb test, started from here.

A backend whose boards exist only inside a running simulator (``cocotb``, ``uart``) is run in two
processes. The launching one (``cosim.launch.cocotb_sim``, ``cosim.launch.uart_sim``) writes the
Verilog, passes the run's configuration and options to the simulator in two environment
variables (:func:`launch_env`) and starts the cocotb test (:func:`run_in_simulator`); the test
(``cosim.launch.cocotb_test``, ``cosim.launch.uart_test``) reads them back
(:func:`read_launch_env`) and runs the lifetime of ``cosim.online.run`` on the boards of its
backend (:func:`lifetime_in_simulator`), writing ``summary.json`` for the launcher to read.
"""

from __future__ import annotations

import json
from pathlib import Path

from base import environ

CONFIG_ENV = "EHW_ONLINE_CONFIG"  # the OnlineConfig, JSON
OPTIONS_ENV = "EHW_ONLINE_OPTIONS"  # out, resume, plots, progress and the backend's own, JSON


def launch_env(config, options: dict) -> dict[str, str]:
    """The environment that carries ``config`` (an ``OnlineConfig``) and ``options`` to the test."""
    return {CONFIG_ENV: json.dumps(config.to_dict()), OPTIONS_ENV: json.dumps(options)}


def read_launch_env() -> tuple[dict, dict]:
    """(config fields, options) of :func:`launch_env`, inside the simulator."""
    return environ.read(CONFIG_ENV), environ.read(OPTIONS_ENV)


def lifetime_in_simulator(config: dict, options: dict, backend: str, *, checkpoint: bool = True):
    """The blocking lifetime (in cocotb's bridge thread): (the run, its summary), written to
    ``options["out"]``."""
    from cosim.online.config import OnlineConfig
    from cosim.online.report import write_results
    from cosim.online.run import make_run

    out = Path(options["out"])
    run = make_run(OnlineConfig(**config), backend, out if checkpoint else None,
                   resume=bool(options.get("resume")), progress=bool(options.get("progress")))
    run.run()
    return run, write_results(run, out, plots=bool(options.get("plots")))


def prepare_out(out) -> Path:
    """The run's output folder, absolute and made, without a summary of an earlier run in it."""
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)
    return out


def run_in_simulator(out: Path, **run_cocotb_args) -> dict:
    """Run a cocotb test (``cosim.boards.cocotb_run.run_cocotb``'s arguments) that writes
    ``out/summary.json``; returns that summary."""
    from cosim.boards.cocotb_run import REPO_ROOT, run_cocotb

    run_cocotb(test_dir=REPO_ROOT, **run_cocotb_args)
    return json.loads((Path(out) / "summary.json").read_text())


def print_summary(summary: dict, out, extra_lines=()) -> None:
    """The table every backend prints, then ``extra_lines`` and where the summary went."""
    from cosim.online.report import summary_table

    print(summary_table(summary))
    for line in extra_lines:
        print(line)
    print(f"wrote {Path(out) / 'summary.json'}")
