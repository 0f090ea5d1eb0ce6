"""``ehw gatesim TARGET``: a bitstream target's synthesised netlist driven through its UART pins by
the unchanged host code, checked against the NumPy reference -> ``results/gatesim.json``.

    make gatesim                                  every target (GATESIM_TARGETS=...)
    ehw gatesim icebreaker-controller             the smallest: genomes and motions over the link
    ehw gatesim icebreaker-evaluator --targets 1  both iCEBreakers in one simulation, a lifetime
    ehw gatesim --netlist pnr icebreaker-controller  the netlist nextpnr placed and routed (iCE40)

The netlist is the board top as ``make bitstream`` builds it (``hdl.gatesim.synthesize``: the
platform's clock pin and power-on reset, the UART at the real baud divisor), simulated with the
vendor cell models in Verilator (or Icarus); with ``--netlist pnr`` the netlist nextpnr placed and
routed for the bitstream (``hdl.gatesim.place_and_route``, iCE40). Per target the check (``CHECKS``):

- ``motions`` (``icebreaker-controller``, ``ulx3s-learner``): IDENTIFY, then ``--genomes``
  seeded random genomes each sent with LOAD_CONTROLLER and asked MOTION in ``--states`` states
  (reflex on and off); every motion is compared with the reference controller as it arrives.
- ``lifetime`` (``icebreaker-evaluator``: the controller and evaluator iCEBreakers side by side;
  ``ulx3s-system``): an on-line lifetime (``--targets``, ``--population``,
  ``--generations-per-phase``) on the boards of the ``serial`` backend, each with the reference
  beside it; then its summary and motion sequence are compared with the same lifetime on the
  reference backend.
- ``ulx3s-learner --ga hardware``: a lifetime whose learning phases run on the netlist's engine
  (``cosim.link.learning``, the ``serial`` backend's ``--ga hardware`` boards, the reference
  engine beside it). The bitstream's engine holds 500 individuals, whose upload alone would take
  ~18 hours at gate level, so this netlist is the same top synthesised for the lifetime's
  ``--population``, ``--tournament`` and ``--lanes`` (default the bitstream's 7), its link at
  the fastest baud its clock allows (``--baud``; 4 cycles a bit, so the engine's cycles, not the
  line's, fill the simulation; the bitstream's own top at 115,200 is the motions check).

``results/gatesim.json`` holds ``targets.<target>`` (``<target>:pnr`` for the routed netlist,
``ulx3s-learner:engine`` for the lifetime on the engine): ``netlist`` (kind, tool), ``simulator``,
``check``, ``interactions``, ``equal_to_reference``, ``wall_s`` (synthesis and simulation), the
clock, baud and divisor, the bytes over the line, and for a lifetime its configuration.
"""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

from cosim.launch.lifetime import launch_env, prepare_out

RESULTS = Path("results/gatesim.json")
OUT_ROOT = Path("build/gatesim/runs")
TOPLEVEL = "gate_harness"
CHECKS = {"icebreaker-controller": "motions", "icebreaker-evaluator": "lifetime",
          "ulx3s-system": "lifetime", "ulx3s-learner": "motions"}
DEFAULT_TARGETS = ("icebreaker-controller", "icebreaker-evaluator", "ulx3s-system")
# Summary keys that depend on the backend or the machine, not on the lifetime.
_NOT_COMPARED = {"backend", "wall_time_s", "board_cycles", "hardware", "phases", "targets"}


def _roles(target: str, check: str) -> dict[str, str]:
    """Board role -> bitstream target of the simulation of ``target``."""
    from hdl.gatesim import PAIR

    if target == "icebreaker-evaluator":
        return dict(zip(("controller", "evaluator"), PAIR))
    return {"controller" if check == "motions" else "system": target}


def learns_on_engine(target: str, config) -> bool:
    """Whether the check of ``target`` is a lifetime on its learning engine (``--ga hardware``)."""
    return target == "ulx3s-learner" and config is not None and config.ga == "hardware"


def _icarus_version() -> str:
    try:
        out = subprocess.run(["iverilog", "-V"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return "icarus"
    return out.splitlines()[0] if out else "icarus"


def _verilator_version() -> str:
    from importlib import metadata

    try:
        return f"Verilator {metadata.version('verilator')}"
    except metadata.PackageNotFoundError:
        return "verilator"


def _compared(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in _NOT_COMPARED}


def reference_lifetime(config) -> tuple[dict, list[int]]:
    """The same lifetime on the reference backend: (summary, motions)."""
    from cosim.online.run import make_run

    run = make_run(config, "reference", None).run()
    return run.summary(), list(run.motions)


def run_gatesim(target: str, *, config=None, genomes: int = 3, states: int = 24, seed: int = 1,
                out: Path | str | None = None, progress: bool = True, simulator: str = "verilator",
                kind: str = "synth", quick_build: bool = False, engine_baud: float | None = None,
                print_=print) -> dict:
    """Synthesise ``target``'s board top(s), simulate the check of ``CHECKS[target]`` and return
    its ``results/gatesim.json`` entry (``config``: the lifetime's ``OnlineConfig``; ``kind``:
    ``synth``, Yosys's netlist, or ``pnr``, nextpnr's placed and routed one;
    ``quick_build``: Verilator's C++ compiled without optimisation, minutes sooner for a short
    check, the simulation itself slower; ``engine_baud``: the link's baud of the engine's top for
    ``--ga hardware``; None: the fastest its clock allows, 4 cycles a bit: at the bitstream's
    115,200 baud the bytes would take ~97 % of the lifetime's ~40 M gate-level cycles, and that
    baud on the bitstream's own top is what the motions check shows)."""
    from cosim.boards.cocotb_run import REPO_ROOT, CocotbFailure, run_cocotb
    from cosim.link.simulated import host_timeout_s
    from hdl.gatesim import (cell_models, check_modelled, harness_verilog, place_and_route, simulator_flags,
                             synthesize)
    from hdl.system_top import P_MAX
    from hdl.uart import uart_divisor

    engine = None
    check = CHECKS[target]
    if learns_on_engine(target, config):
        from cosim.online.learning_phase import hardware_ga_config

        check, engine = "lifetime", hardware_ga_config(config)
        if engine_baud is None:
            from hdl.fpga import TARGETS
            from hdl.uart import max_baud

            engine_baud = float(max_baud(TARGETS[target].pll_hz))
    t0 = time.perf_counter()
    if kind == "synth":
        netlists = {role: synthesize(name, progress=print_, engine=engine, baud=engine_baud)
                    for role, name in _roles(target, check).items()}
    else:
        netlists = {role: place_and_route(name, progress=print_) for role, name in _roles(target, check).items()}
    synth_s = time.perf_counter() - t0
    first = next(iter(netlists.values()))
    variant = f"{Path(first.directory).name}_{kind}"  # the engine's folder for --ga hardware
    out = prepare_out(OUT_ROOT / variant.removesuffix("_synth") if out is None else out)
    for stale in ("motions.json", "link.json", "error.json"):
        (out / stale).unlink(missing_ok=True)
    harness = first.directory / f"{TOPLEVEL}_{variant}.v"
    harness.write_text(harness_verilog(netlists, TOPLEVEL))
    # a folder of their own: Yosys would take a copied .vh in its working folder for its own
    models = cell_models(first.directory / "cells", first.family, simulator)
    for netlist in netlists.values():  # a cell without a model would simulate as a black box
        check_modelled(netlist.path, models)
    sources = [harness, *[Path(n.path) for n in netlists.values()], *models]
    includes = [f"-I{d}" for d in dict.fromkeys([first.directory, *(Path(m).parent for m in models)])]
    options = {"out": str(out), "target": target, "roles": list(netlists), "progress": progress,
               "clk_freq_hz": first.clk_freq_hz, "seed": seed, "genomes": genomes, "states": states,
               "host_timeout_s": host_timeout_s(first.baud, P_MAX)}
    if check == "lifetime":
        if config is None:
            raise ValueError("a lifetime check needs its OnlineConfig")
        env = launch_env(config, options)
    else:
        from cosim.online.config import OnlineConfig

        env = launch_env(OnlineConfig(), options)
    print_(f"{target}: simulating the netlist{'s' if len(netlists) > 1 else ''} in {simulator} "
           f"({', '.join(netlists)}; {first.clk_freq_hz / 1e6:g} MHz, {first.baud:,.0f} baud)")
    t1 = time.perf_counter()
    error = None
    try:
        run_cocotb(sources=sources, toplevel=TOPLEVEL, test_module="cosim.launch.gatesim_test",
                   test_dir=REPO_ROOT, build_name=f"gatesim_{variant}", testcase=f"gate_{check}",
                   extra_env=env, simulator=simulator,
                   build_args=[*simulator_flags(first.family, simulator), *includes,
                               *(("-CFLAGS", "-O0") if quick_build and simulator == "verilator" else ())])
    except CocotbFailure as exc:
        error = str(exc)
    except RuntimeError as exc:  # the simulator could not build the netlist (its log is above)
        error = f"{simulator} could not build the netlist: {exc}"
    sim_s = time.perf_counter() - t1
    entry = {
        "netlist": {"kind": first.kind,
                    "tool": (f"Yosys synth_{first.family}, write_verilog -noattr" if kind == "synth" else
                             f"nextpnr-{first.family} --write (placed and routed), Yosys read_json, "
                             "write_verilog -noattr; functional, no SDF delays"),
                    "modules": {role: n.module for role, n in netlists.items()},
                    "cell_models": [Path(p).name for p in sources[1 + len(netlists):]]},
        "simulator": _icarus_version() if simulator == "icarus" else _verilator_version(), "check": check,
        "design": {role: n.design for role, n in netlists.items()},
        "clock_hz": first.clk_freq_hz, "baud": first.baud,
        "divisor": uart_divisor(first.clk_freq_hz, first.baud),
        "synth_s": round(synth_s, 1), "sim_s": round(sim_s, 1), "wall_s": round(synth_s + sim_s, 1),
        "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    entry.update(_outcome(check, out, config, error))
    return entry


def _outcome(check: str, out: Path, config, error: str | None) -> dict:
    """interactions, equal_to_reference (and why not) of a finished simulation."""
    motions_file = out / "motions.json"
    if error is not None or not motions_file.exists():
        said = out / "error.json"  # what the host code raised inside the simulation
        return {"interactions": None, "equal_to_reference": False,
                "error": json.loads(said.read_text())["error"] if said.exists() else
                error or "the simulation wrote no motions.json"}
    got = json.loads(motions_file.read_text())
    if check == "motions":
        # every motion was compared with the reference controller as it came (LinkMismatch)
        return {"interactions": got["interactions"], "equal_to_reference": True,
                "link": {k: got[k] for k in ("bytes_sent", "bytes_received", "requests", "resends")}}
    summary = json.loads((out / "summary.json").read_text())
    ref_summary, ref_motions = reference_lifetime(config)
    differs = sorted(k for k in set(_compared(summary)) | set(_compared(ref_summary))
                     if summary.get(k) != ref_summary.get(k))
    link = json.loads((out / "link.json").read_text())
    return {"interactions": summary["interactions"],
            "equal_to_reference": not differs and got["motions"] == ref_motions,
            "summary_differs": differs, "motions_equal": got["motions"] == ref_motions,
            "targets_reached": summary["targets_reached"], "learning_phases": summary["learning_phases"],
            "config": {k: v for k, v in config.to_dict().items()
                       if k in ("seed", "n_targets", "population", "tournament", "generations_per_phase", "ga")}
            | ({"lanes": config.lanes} if config.ga == "hardware" else {}),
            "link": {role: {k: v[k] for k in ("bytes_sent", "bytes_received", "requests", "resends")}
                     for role, v in link.items()}}


def write_results(path: Path | str, target: str, entry: dict) -> dict:
    """Merge ``entry`` into ``path`` under ``targets.<target>`` (other targets are kept)."""
    from base.files import atomic_write_json

    path = Path(path)
    data = json.loads(path.read_text()) if path.exists() else {}
    data.setdefault("targets", {})[target] = entry
    atomic_write_json(path, data)
    return data
