"""Round 12 of the on-line search (docs/online.md, "Round 12"): the robot's left-right mirror
symmetry in the world model.

    python experiments/online_round12.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round12.py mirror_fill 1-4
    python experiments/online_round12.py mirror_full 1-4 --param states=known
    python experiments/online_round12.py --table build/experiments/round12.jsonl   # against the defaults

A lifetime is round 11's (``experiments.online_round11.Round11``, so ``default`` is ``ehw sim``'s
lifetime). New here, host side: the sensor layout and the motion set are mirror-symmetric (SPEC
section 4; ``ga.motions.MIRROR_STATE``, ``MIRROR_MOTION``), so every real observation
(s, a) -> s2 (or a crash) is evidence of (m(s), m(a)) -> m(s2). After each real observation the
host sends the evaluator board one more observation, the mirrored one, through the same
``observe`` (the board's model write port), and applies it to its own copy (``self.mirror``), so
both hold the same model. The rule that decides whether the mirrored observation is written:

- ``mirror_fill``: only into an entry the model does not know yet (a real observation always
  wins; with ``refresh`` = 1 a mirrored entry is also updated by later mirrored observations
  until the robot itself executes that pair);
- ``mirror_crash``: only crashes, into unknown or non-crash entries (crash entries stay
  permanent); with ``unknown_only`` = 1 into unknown entries only;
- ``mirror_full``: every mirrored observation, applied like a real one (most recent wins, a
  crash entry is never overwritten).

A mirrored crash records next state m(s) (a crash entry holds its own state; the put-back
observation is the robot's own, already in S). ``states``: ``add`` (default) lets a mirrored
write add m(s) and m(s2) to S like a real one (the invariant "every next state of a valid entry is
in S" holds, and N, the fitness's normalisation, counts them); ``known`` writes a mirrored
observation only when both states are already in S (the robot has been in them; N unchanged).
A pair that is its own mirror image (m(s) = s, m(a) = a) is not written twice. The variant
``mirror`` takes the rule from ``--param mirror=fill|crash|full``, to combine it with another
round's variant (e.g. ``likely --param mirror=fill``).

The round's symmetry check (``experiments/online_round12_symmetry.py``) found the mirrored
*latest* outcome a poor prediction and the mirrored *most frequent* outcome nearly as good as the
pair's own; variant ``mode``: the host counts each pair's non-crash outcomes and keeps each
non-crash entry at its most frequent outcome (ties: the latest met; one more write through the
board's ``observe`` after the real one when it differs), a change of SPEC section 7's "most recent
outcome wins"; crash entries stay permanent. ``pool`` = 1: a real outcome also counts, mirrored,
for the mirrored pair (whose entry then holds its pooled most frequent outcome; a new entry adds
its states to S).

The second idea of the round, not the mirror: ``likely_untried`` subtracts both round 10's
``likely`` penalty and round 11's revised distance term (``distance``) from the SPEC fitness, the
two best ratios on the screening seeds (``--param cycles=3 --param untried=0.5``: 0.90 and 0.89).
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round11 import DEFAULT_PARAMS as R11_PARAMS  # noqa: E402
from experiments.online_round11 import VARIANTS as R11_VARIANTS  # noqa: E402
from experiments.online_round11 import Round11  # noqa: E402
from experiments.online_round11 import table as round11_table  # noqa: E402
from ga.motions import MIRROR_MOTION, MIRROR_STATE, N_MOTIONS, N_STATES  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round12.jsonl")
# their ``default`` rows: today's defaults (round 9's: seeds 1-16, round 10's: 17-24, round 11's: 141-160)
REFERENCES = tuple(Path(f"build/experiments/round{k}.jsonl") for k in (9, 10, 11))
MIRROR_RULES = ("fill", "crash", "full")
VARIANTS = (*R11_VARIANTS, *(f"mirror_{rule}" for rule in MIRROR_RULES), "likely_untried", "mode")
STATE_RULES = ("add", "known")
HELD_OUT = range(161, 181)  # never used to choose (101-120: rounds 8-10's defaults; 141-160: round 11's)
R12_PARAMS = {"mirror": "", "states": "add", "refresh": 0, "pool": 0, "unknown_only": 0}
DEFAULT_PARAMS = {**R11_PARAMS, **R12_PARAMS}


def mirrored(state: int, motion: int, next_state: int, crashed: bool) -> tuple[int, int, int, bool]:
    """The mirror image of one observation (a crash records its own state, see the docstring)."""
    ms = int(MIRROR_STATE[state])
    return ms, int(MIRROR_MOTION[motion]), ms if crashed else int(MIRROR_STATE[next_state]), bool(crashed)


class Round12(Round11):
    """Round 11's lifetime with the mirrored observations of this round."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.rule = self.variant.removeprefix("mirror_") if self.variant.startswith("mirror_") else self.params["mirror"]
        if self.rule not in ("", *MIRROR_RULES):
            raise ValueError(f"--param mirror must be one of {MIRROR_RULES!r}, got {self.rule!r}")
        if self.params["states"] not in STATE_RULES:
            raise ValueError(f"--param states must be one of {STATE_RULES!r}, got {self.params['states']!r}")
        self.real = np.zeros((N_STATES, N_MOTIONS), dtype=bool)  # pairs the robot executed
        self.real_states = np.zeros(N_STATES, dtype=bool)  # states the robot has been in
        self.real_states[self.state] = True
        self.mirror_log: Counter = Counter()
        self.tallies: dict[tuple[int, int], dict[int, tuple[int, int]]] = {}  # mode: outcome -> (count, last met)
        self.clock = 0

    def step(self, motion, record=True):
        s, model = self.state, self.mirror
        # instrumentation: does the executed pair's entry, real or mirrored, say what happens?
        source = "" if not model.valid[s, motion] else "real" if self.real[s, motion] else "mirrored"
        said = (bool(model.crash[s, motion]), int(model.next_state[s, motion]))
        step = super().step(motion, record)
        if source:
            outcome = (bool(step.crashed), s if step.crashed else int(step.state))
            self.mirror_log[f"{source}_{'confirmed' if said == outcome else 'surprise'}"] += 1
        self.real[s, motion] = True
        self.real_states[[s, step.state]] = True
        if self.rule:
            self.write_mirrored(s, int(motion), int(step.state), bool(step.crashed))
        if self.variant == "mode":
            self.write_modes(s, int(motion), int(step.state), bool(step.crashed))
        return step

    def write_modes(self, s: int, a: int, s2: int, crashed: bool) -> None:
        """``mode``: count the outcome (and with ``pool`` its mirror image for the mirrored pair),
        then make each non-crash entry concerned hold its most frequent outcome (ties: the latest
        met), written through the board's ``observe`` like an observation."""
        if crashed:
            return  # the entry is a crash now, for ever
        pairs = [(s, a, s2)]
        ms, ma, ms2, _ = mirrored(s, a, s2, False)
        if self.params["pool"] and (ms, ma) != (s, a):
            pairs.append((ms, ma, ms2))
        model = self.mirror
        for ps, pa, nxt in pairs:
            self.clock += 1
            tally = self.tallies.setdefault((ps, pa), {})
            count, _ = tally.get(nxt, (0, 0))
            tally[nxt] = (count + 1, self.clock)
            if model.crash[ps, pa]:
                continue
            best = max(tally, key=tally.get)  # (count, last met)
            if model.valid[ps, pa] and int(model.next_state[ps, pa]) == best:
                continue
            self.evaluator.observe(ps, pa, best, False)
            model.observe(ps, pa, best, False)
            self.mirror_log["mode_written" if (ps, pa) == (s, a) else "mode_mirrored"] += 1

    def write_mirrored(self, s: int, a: int, s2: int, crashed: bool) -> None:
        """The mirrored observation, sent to the board and the host copy when the rule allows it."""
        ms, ma, ms2, crashed = mirrored(s, a, s2, crashed)
        model, log = self.mirror, self.mirror_log
        if (ms, ma) == (s, a):
            return  # its own mirror image: the real observation is this entry
        known = bool(model.valid[ms, ma])
        if self.rule == "crash" and (not crashed or (known and self.params["unknown_only"])):
            return
        if self.rule == "fill" and known and (self.real[ms, ma] or not self.params["refresh"]):
            return
        if model.crash[ms, ma]:
            log["kept_crash"] += 1
            return  # a crash entry is never overwritten (and S gains nothing the real rule would add)
        if self.params["states"] == "known" and not (model.in_set[ms] and model.in_set[ms2]):
            log["outside_s"] += 1
            return
        before = (known, int(model.next_state[ms, ma]))
        self.evaluator.observe(ms, ma, ms2, crashed)
        model.observe(ms, ma, ms2, crashed)
        log["crash" if crashed else "written"] += 1
        if not known:
            log["new_entry"] += 1
        elif before[1] != ms2 and not crashed:
            log["changed_entry"] += 1

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        if self.variant.startswith("mirror") or self.variant == "mode":
            return np.zeros(len(pop))  # the SPEC fitness, to the bit
        if self.variant == "likely_untried":
            return self.penalty_of(truth_tables(pop, reflex=self.config.reflex), n)
        return super().penalty(pop, n)

    def penalty_of(self, tables: np.ndarray, n: int) -> np.ndarray:
        if self.variant != "likely_untried":
            return super().penalty_of(tables, n)
        # round 10's likely cycles plus round 11's revised distance term, each as its round has it
        return self._penalty_as("likely", tables, n) + self._penalty_as("distance", tables, n)

    def _penalty_as(self, variant: str, tables: np.ndarray, n: int) -> np.ndarray:
        self.variant = variant  # an instance attribute over the class's, for the one call
        try:
            return Round11.penalty_of(self, tables, n)
        finally:
            del self.variant

    def extra_figures(self) -> dict:
        model = self.mirror
        return {**super().extra_figures(),
                "mirror": {**self.mirror_log, "model_states": model.n_states,
                           "model_transitions": model.n_transitions, "model_crashes": model.n_crashes,
                           "real_states": int(self.real_states.sum()), "real_pairs": int(self.real.sum()),
                           "mirrored_entries": int((model.valid & ~self.real).sum()),
                           "states_never_visited": int((model.in_set & ~self.real_states).sum())}}


def table(path: Path) -> str:
    """Round 11's table with this round's references and held-out seeds."""
    return round11_table(path, REFERENCES, HELD_OUT)


def main(argv=None) -> int:
    return round8_main(argv, cls=Round12, defaults=DEFAULT_PARAMS, variants=(*VARIANTS, "mirror"),
                       default_out=DEFAULT_OUT, description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
