"""``ehw gatesim [TARGET ...]``: the bitstream targets' synthesised netlists driven by the host code
(``cosim.launch.gatesim``) -> ``results/gatesim.json``.

Exit status 0 when every target's netlist gave the reference's motions (and lifetime), 1 when
one did not, 2 for a user error (an unknown target, a missing tool).
"""

from __future__ import annotations

from pathlib import Path


def gatesim_parser(p) -> None:
    from cosim.launch.gatesim import CHECKS, DEFAULT_TARGETS, RESULTS
    from ga.hardware_ga import LEARNER_LANES

    p.add_argument("target_names", nargs="*", metavar="TARGET",
                   help=f"bitstream targets ({', '.join(CHECKS)}; default: {', '.join(DEFAULT_TARGETS)})")
    p.add_argument("--simulator", choices=("verilator", "icarus"), default="verilator",
                   help="Verilator (compiles the netlist: minutes, then ~50x Icarus) or Icarus "
                        "(default: %(default)s)")
    p.add_argument("--netlist", choices=("synth", "pnr"), default="synth",
                   help="Yosys's synthesised netlist, or nextpnr's placed and routed one (the "
                        "bitstream's placement, seed 1) (default: %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="the lifetime's seed; the motions check's genomes (default: %(default)s)")
    motions = p.add_argument_group("the motions check (icebreaker-controller, ulx3s-learner)")
    motions.add_argument("--genomes", type=int, default=3, help="random genomes loaded (default: %(default)s)")
    motions.add_argument("--states", type=int, default=24, help="states asked per genome (default: %(default)s)")
    life = p.add_argument_group("the lifetime check (icebreaker-evaluator: both iCEBreakers; ulx3s-system; "
                                "ulx3s-learner --ga hardware)")
    life.add_argument("--targets", type=int, default=4, help="targets of the lifetime (default: %(default)s)")
    life.add_argument("--population", type=int, default=4, help="GA population (default: %(default)s)")
    life.add_argument("--tournament", type=int, default=2, help="GA tournament (default: %(default)s)")
    life.add_argument("--generations-per-phase", type=int, default=1, help="(default: %(default)s)")
    life.add_argument("--ga", choices=("host", "hardware"), default="host",
                      help="hardware: ulx3s-learner's lifetime with its learning on the netlist's "
                           "engine, synthesised for --population, --tournament and --lanes (the "
                           "bitstream's 500 individuals take ~18 hours to upload at gate level) "
                           "(default: %(default)s: ulx3s-learner runs the motions check)")
    life.add_argument("--lanes", type=int, default=LEARNER_LANES,
                      help="--ga hardware: the engine's lanes (default: %(default)s, the bitstream's)")
    life.add_argument("--baud", type=float, default=None,
                      help="--ga hardware: the engine top's link baud (default: the fastest the 30 MHz "
                           "clock allows, 7.5 Mbaud, 4 cycles a bit; the motions check runs the "
                           "bitstream's own top at its 115,200)")
    life.add_argument("--max-interactions", type=int, default=40,
                      help="stop the lifetime after this many interactions: every byte costs "
                           "~1,000-2,000 gate-level clock cycles (default: %(default)s)")
    p.add_argument("--results", type=Path, default=RESULTS, help="results file (default: %(default)s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar for the lifetime")


def cmd_gatesim(args, extras: dict, sub=None) -> int:
    from base.errors import UserError
    from cosim.launch.gatesim import CHECKS, DEFAULT_TARGETS, run_gatesim, write_results
    from cosim.online.config import OnlineConfig

    names = args.target_names or list(DEFAULT_TARGETS)
    unknown = [n for n in names if n not in CHECKS]
    if unknown:
        raise UserError(f"unknown target(s) {', '.join(map(repr, unknown))}; known: {', '.join(CHECKS)}")
    for flag in ("genomes", "states", "targets", "population", "tournament", "generations_per_phase",
                 "max_interactions", "lanes"):
        if getattr(args, flag) < 1:
            raise UserError(f"--{flag.replace('_', '-')} must be at least 1, got {getattr(args, flag)!r}")
    try:
        config = OnlineConfig(seed=args.seed, n_targets=args.targets, population=args.population,
                              tournament=args.tournament, generations_per_phase=args.generations_per_phase,
                              max_interactions=args.max_interactions, ga=args.ga, lanes=args.lanes)
    except (TypeError, ValueError) as exc:
        raise UserError(f"the lifetime's options: {exc}") from None
    if args.baud is not None and args.ga != "hardware":
        raise UserError("--baud: only the engine's top (ulx3s-learner --ga hardware) is built at another baud; "
                        "the others run the bitstream's own top")
    if args.baud is not None:
        from hdl.fpga import TARGETS
        from hdl.uart import uart_divisor

        try:
            uart_divisor(TARGETS["ulx3s-learner"].pll_hz, args.baud)
        except ValueError as exc:
            raise UserError(f"--baud {args.baud:g}: {exc}") from None
    if args.ga == "hardware" and (names != ["ulx3s-learner"] or args.netlist != "synth"):
        raise UserError("--ga hardware: the lifetime on the learning engine is ulx3s-learner's, on its "
                        f"synthesised netlist (ehw gatesim ulx3s-learner --ga hardware), not {' '.join(names)}"
                        + (f" --netlist {args.netlist}" if args.netlist != "synth" else ""))
    if args.netlist == "pnr":
        from hdl.fpga import TARGETS
        from hdl.gatesim import PNR_FAMILIES

        routed = [n for n in CHECKS if TARGETS[n].family in PNR_FAMILIES]
        other = [n for n in names if n not in routed]
        if other:
            raise UserError(f"--netlist pnr: the placed and routed netlist is simulated for {', '.join(routed)} "
                            f"only, not {', '.join(other)}")
    failed = []
    for name in names:
        entry = run_gatesim(name, config=config, genomes=args.genomes, states=args.states, seed=args.seed,
                            simulator=args.simulator, kind=args.netlist, progress=not args.no_progress,
                            engine_baud=args.baud)
        key = f"{name}:pnr" if args.netlist == "pnr" else f"{name}:engine" if args.ga == "hardware" else name
        write_results(args.results, key, entry)
        verdict = "EQUAL to the reference" if entry["equal_to_reference"] else "DIFFERS from the reference"
        print(f"{name}: {entry['check']} on the {entry['netlist']['kind']} netlist in {entry['simulator']}: "
              f"{entry['interactions']} interactions, {verdict} ({entry['wall_s']:.0f} s)"
              + (f"\n{name}: {entry['error']}" if entry.get("error") else ""), flush=True)
        if not entry["equal_to_reference"]:
            failed.append(name)
    print(f"wrote {args.results}")
    return 1 if failed else 0
