"""The options of ``ehw sim`` (the on-line experiment): :func:`add_arguments` puts them on a
parser, :func:`config_from_args` turns the parsed options into a
:class:`cosim.online.config.OnlineConfig` (an invalid value is a ``ValueError`` naming the option).
``cosim.cli.commands`` adds the run folder, the config file and the checks of every run.
"""

from __future__ import annotations

import argparse

from base.options import add_field_options
from cosim.boards.registry import BACKENDS
from cosim.online.config import LOOP_BLAMES, OPTIONS, OnlineConfig
from ga.motions import DISTANCE_RULES

RATES = ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate")

# The OnlineConfig fields whose option is ``--<field>`` (the others: OPTIONS, and the pairs below).
FIELD_HELP = {
    "seed": "the run's seed (the world, the course, the GA)",
    "arena": "the arena: a shipped name (ehw arena) or a JSON file",
    "noise": "the noisy 'real' world (sim_world.world.DEFAULT_NOISE)",
    "range_noise": "relative error of the camera's range estimate, all the robot learns progress "
                   "from (SPEC section 4; with --noise)",
    "reflex": "the reflex in free space (SPEC section 6)",
    "population": "GA population of a learning phase (SPEC section 7)",
    "tournament": "GA tournament size",
    "elitism": "GA elite kept each generation",
    "generations_per_phase": "GA generations of one learning phase",
    **{rate: "GA rate (ga.evolution.GAConfig)" for rate in RATES},
    "max_leg_steps": "leg time-out (steps)",
    "loop_window": "stop a leg after this many steps without a new closest approach (0: off)",
    "loop_reentries": "stop a leg at this many entries into one obstacle state (0: off)",
    "loop_repeats": "stop a leg at this many repetitions of one short (state, motion) cycle (0: off)",
    "loop_radius_mm": "--loop-reentries, --loop-repeats and --loop-cycles fire only if the robot is "
                      "back within this distance by odometry (0: off)",
    "loop_cycles": "stop a leg once the robot has gone K times round one simple cycle of states back "
                   "to where it is (SPEC section 7: 1; 0: off, the first reading)",
    "cycles_after_approach": "the cycle stop counts only rounds since the last new closest approach by "
                             "the camera's range (before issue 36); default: odometry alone",
    "max_interactions": "end the lifetime after this many interactions even short of the targets (0: never)",
    "escape": "after a time-out or loop, download the best that avoids the blamed motion",
    "fail_rates": "the robot's own failure rate of each (state, motion) as a fourth fitness term "
                  "(SPEC section 7, ga.fail_rates; --no-fail-rates: the three terms of the paper)",
    "rate_mirror": "with --fail-rates, each pair's rate code pools its counts with its left-right "
                   "mirror image's (--no-rate-mirror: each pair's own counts)",
    "loop_blame": "the (state, motion) a cycle stop is blamed on: cycle = the first pair of the cycle "
                  "that stopped the leg, leg = the leg's most frequent obstacle pair",
    "ga": "the learning phases' GA: the host's NumPy GA or the learning board's hardware GA "
          "(SPEC section 12, docs/learner.md)",
    "lanes": "evaluator lanes of --ga hardware (default: the ulx3s-learner bitstream's)",
}
FIELD_EXTRA = {**{rate: {"metavar": "P"} for rate in RATES}, "range_noise": {"metavar": "SD"},
               "loop_cycles": {"metavar": "K"},
               "loop_blame": {"choices": LOOP_BLAMES}, "ga": {"choices": ("host", "hardware")}}


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = OnlineConfig()
    p.add_argument("--backend", choices=BACKENDS, default="reference",
                   help="the boards: NumPy reference, Amaranth's simulator, cocotb on the Verilog, "
                        "real boards on a serial port, the link top in Verilator (uart)")
    add_field_options(p, d, FIELD_HELP, extra=FIELD_EXTRA)
    p.add_argument(OPTIONS["n_targets"], type=int, default=d.n_targets, help="targets of the lifetime")
    p.add_argument("--continue-past-64", type=int, default=0, metavar="N",
                   help="go on for N more targets after the 64th (Fig. 11)")
    p.add_argument("--blind-bit", type=int, default=None, metavar="B", help="IR bit 0..5 to blind (stuck at 0)")
    p.add_argument("--blind-after-target", type=int, default=None, metavar="T",
                   help="with --blind-bit: blind it from this target on")
    p.add_argument(OPTIONS["distance_rule"], choices=DISTANCE_RULES, default=d.distance_rule,
                   help="dist[a] of the fitness: forward = SPEC section 7 (backward motions cover "
                        "0); covered = the paper's first reading (every translation)")
    p.add_argument("--progress-weight", type=float, default=None,
                   help="with --fail-rates, each rate code also carries the pair's progress deficit "
                        "(its mean gain towards the ball over the next 8 steps against its state's "
                        f"best) with this weight (default {d.progress_weight}; 0: none)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    return p


def config_from_args(args) -> OnlineConfig:
    """The OnlineConfig of parsed options (ValueError naming the option for a bad value)."""
    progress = OnlineConfig.progress_weight if args.progress_weight is None else args.progress_weight
    if args.progress_weight and not args.fail_rates:
        raise ValueError("--progress-weight needs --fail-rates (the deficit rides on the rate codes)")
    return OnlineConfig(
        **{name: getattr(args, name) for name in FIELD_HELP},
        n_targets=args.targets + args.continue_past_64, distance_rule=args.distance,
        progress_weight=progress, blind_bit=args.blind_bit, blind_after_target=args.blind_after_target)


def build_parser() -> argparse.ArgumentParser:
    """A parser of these options alone (``ehw sim`` adds the run's flags to them)."""
    return add_arguments(argparse.ArgumentParser(prog="ehw sim"))
