"""The command line of the on-line experiment (``make sim``, ``python -m cosim.online.run``).

    python -m cosim.online.run [--backend reference|amaranth|cocotb|serial|uart] [--seed 1] [--out DIR] [--resume]
                           [--continue-past-64 N] [--blind-bit B --blind-after-target T] ...

Three pieces, so that another front end (one console script with subcommands) can reuse them:
:func:`add_arguments` puts the options on a parser, :func:`config_from_args` turns the parsed
options into a ``cosim.online.run.OnlineConfig`` (an invalid value is a ``ValueError`` naming the
option), :func:`main` runs the lifetime and prints the table; a user error is one ``error:`` line
on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from base.errors import UserError
from cosim.boards.registry import BACKENDS, launcher
from cosim.online.config import LOOP_BLAMES, OnlineConfig
from cosim.online.learning_phase import check_learning_backend
from cosim.online.run import make_run
from ga.motions import DISTANCE_RULES

DEFAULT_OUT = Path("results/model_based")


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = OnlineConfig()
    p.add_argument("--backend", choices=BACKENDS, default="reference",
                   help="the boards: NumPy reference, Amaranth's simulator, cocotb on the Verilog "
                        "(simulator: EHW_SIM=icarus|verilator; EHW_HDL_SAMPLE=k evaluates k "
                        "controllers a population on the HDL, 0 = all), real boards on a serial "
                        "port (serial: EHW_PORT=...), the link top in Verilator (uart)")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--arena", default=d.arena)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--resume", action="store_true", help="continue from <out>/checkpoint.json")
    p.add_argument("--targets", type=int, default=64, help="targets of the lifetime (default 64)")
    p.add_argument("--continue-past-64", type=int, default=0, metavar="N",
                   help="go on for N more targets after the 64th (Fig. 11)")
    p.add_argument("--blind-bit", type=int, default=None, metavar="B", help="IR bit 0..5 to blind (stuck at 0)")
    p.add_argument("--blind-after-target", type=int, default=None, metavar="T")
    p.add_argument("--noise", action=argparse.BooleanOptionalAction, default=d.noise,
                   help="the noisy 'real' world (sim_world.world.DEFAULT_NOISE)")
    p.add_argument("--range-noise", type=float, default=d.range_noise, metavar="SD",
                   help="relative error of the camera's range estimate, all the robot learns "
                        "progress from (SPEC section 4; with --noise)")
    p.add_argument("--reflex", action=argparse.BooleanOptionalAction, default=d.reflex,
                   help="the reflex in free space (SPEC section 6)")
    p.add_argument("--population", type=int, default=d.population)
    p.add_argument("--tournament", type=int, default=d.tournament)
    p.add_argument("--elitism", type=int, default=d.elitism)
    p.add_argument("--generations-per-phase", type=int, default=d.generations_per_phase)
    for rate in ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate"):
        p.add_argument("--" + rate.replace("_", "-"), type=float, default=getattr(d, rate), metavar="P",
                       help="GA rate (ga.evolution.GAConfig)")
    p.add_argument("--max-leg-steps", type=int, default=d.max_leg_steps, help="leg time-out (steps)")
    p.add_argument("--loop-window", type=int, default=d.loop_window,
                   help="stop a leg after this many steps without a new closest approach (0: off)")
    p.add_argument("--loop-reentries", type=int, default=d.loop_reentries,
                   help="stop a leg at this many entries into one obstacle state (0: off)")
    p.add_argument("--loop-repeats", type=int, default=d.loop_repeats,
                   help="stop a leg at this many repetitions of one short (state, motion) cycle (0: off)")
    p.add_argument("--loop-radius-mm", type=float, default=d.loop_radius_mm,
                   help="--loop-reentries, --loop-repeats and --loop-cycles fire only if the "
                        "robot is back within this distance by odometry (0: off)")
    p.add_argument("--loop-cycles", type=int, default=d.loop_cycles, metavar="K",
                   help="stop a leg once the robot has gone K times round one simple cycle of "
                        "states back to where it is (SPEC section 7: 1; 0: off, the first reading)")
    p.add_argument("--cycles-after-approach", action=argparse.BooleanOptionalAction,
                   default=d.cycles_after_approach,
                   help="the cycle stop counts only rounds since the last new closest approach by the "
                        "camera's range (before issue 36); default --no-cycles-after-approach: odometry alone")
    p.add_argument("--distance", choices=DISTANCE_RULES, default=d.distance_rule,
                   help="dist[a] of the fitness: forward = SPEC section 7 (backward motions cover "
                        "0); covered = the paper's first reading (every translation)")
    p.add_argument("--max-interactions", type=int, default=d.max_interactions,
                   help="end the lifetime after this many interactions even short of the targets (0: never)")
    p.add_argument("--escape", action=argparse.BooleanOptionalAction, default=d.escape,
                   help="after a time-out or loop, download the best that avoids the blamed motion")
    p.add_argument("--fail-rates", action=argparse.BooleanOptionalAction, default=d.fail_rates,
                   help="the robot's own failure rate of each (state, motion) as a fourth fitness "
                        "term (ga.fail_rates; docs/online.md, round 15; default on; --no-fail-rates: "
                        "SPEC section 7's three terms)")
    p.add_argument("--rate-mirror", action=argparse.BooleanOptionalAction, default=d.rate_mirror,
                   help="with --fail-rates, each pair's rate code pools its counts with its left-right "
                        "mirror image's (docs/online.md, round 16; default on; --no-rate-mirror: round 15's codes)")
    p.add_argument("--progress-weight", type=float, default=None,
                   help="with --fail-rates, each rate code also carries the pair's progress deficit "
                        "(its mean gain towards the ball over the next 8 steps against its state's "
                        f"best) with this weight (docs/online.md, round 18; default {d.progress_weight}; 0: none)")
    p.add_argument("--loop-blame", choices=LOOP_BLAMES, default=d.loop_blame,
                   help="the (state, motion) a cycle stop is blamed on: cycle = the first pair of "
                        "the cycle that stopped the leg (default), leg = the leg's most frequent "
                        "obstacle pair (rounds 1-7)")
    p.add_argument("--ga", choices=("host", "hardware"), default=d.ga,
                   help="the learning phases' GA: the host's NumPy GA (default) or the learning "
                        "board's hardware GA (SPEC section 12, docs/learner.md)")
    p.add_argument("--lanes", type=int, default=d.lanes,
                   help="evaluator lanes of --ga hardware (default: the ulx3s-learner bitstream's %(default)s)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    return p


def config_from_args(args) -> OnlineConfig:
    """The OnlineConfig of parsed options (ValueError naming the option for a bad value)."""
    progress = OnlineConfig.progress_weight if args.progress_weight is None else args.progress_weight
    if args.progress_weight and not args.fail_rates:
        raise ValueError("--progress-weight needs --fail-rates (the deficit rides on the rate codes)")
    return OnlineConfig(
        seed=args.seed, arena=args.arena, n_targets=args.targets + args.continue_past_64,
        noise=args.noise, range_noise=args.range_noise, reflex=args.reflex, population=args.population,
        tournament=args.tournament, elitism=args.elitism, generations_per_phase=args.generations_per_phase,
        crossover_rate=args.crossover_rate, literal_rate=args.literal_rate, output_rate=args.output_rate,
        switch_rate=args.switch_rate, replace_rate=args.replace_rate,
        max_leg_steps=args.max_leg_steps, loop_window=args.loop_window,
        loop_reentries=args.loop_reentries, loop_repeats=args.loop_repeats,
        loop_radius_mm=args.loop_radius_mm, loop_cycles=args.loop_cycles,
        cycles_after_approach=args.cycles_after_approach, distance_rule=args.distance,
        escape=args.escape, fail_rates=args.fail_rates, rate_mirror=args.rate_mirror,
        progress_weight=progress, loop_blame=args.loop_blame, max_interactions=args.max_interactions,
        blind_bit=args.blind_bit, blind_after_target=args.blind_after_target,
        ga=args.ga, lanes=args.lanes,
    )


def build_parser() -> argparse.ArgumentParser:
    return add_arguments(argparse.ArgumentParser(
        prog="python -m cosim.cli.online", description="The on-line model-based experiment: one robot lifetime "
        "(paper section 5.2, SPEC section 7)."))


def run(config: OnlineConfig, args) -> int:
    """Run the lifetime of ``config`` with the other parsed ``args``; print the table (exit status)."""
    from cosim.online.report import summary_table, write_results

    launch = launcher(args.backend)
    check_learning_backend(config, args.backend)
    if launch is not None:  # the loop must run inside the simulator (cocotb): the launcher starts it
        return launch(config, args)
    run = make_run(config, args.backend, args.out, resume=args.resume, progress=not args.no_progress)
    run.run()
    summary = write_results(run, args.out, plots=not args.no_plots)
    print(summary_table(summary))
    print(f"wrote {args.out / 'summary.json'}" + (f" and {len(summary.get('plots', []))} plots" if not args.no_plots else ""))
    return 0


def _error(exc: Exception) -> int:
    print(f"error: {exc}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        config = config_from_args(args)
    except ValueError as exc:
        return _error(exc)
    try:
        return run(config, args)
    except UserError as exc:  # CheckpointError, BackendUnavailable, a link's LinkError, ...
        return _error(exc)


if __name__ == "__main__":  # ``python -m cosim.cli.online``; ``ehw sim`` adds run folders and checks
    raise SystemExit(main())
