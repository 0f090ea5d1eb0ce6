"""The hardware GA of SPEC section 12: the bit-exact NumPy reference of ``hdl.learner``.

The learning engine on the chip runs the GA itself: the population in on-chip RAM, ``lanes``
evaluator lanes, and a random source made of xorshift32 generators. This module is the same
algorithm in NumPy, so that the same seed gives the same populations, the same scores and the
same best controller here and in the HDL. The host GA (``ga.evolution``, a NumPy ``Generator``)
stays as it is; this one is designed so the hardware needs few resources:

Random source
-------------
Seven xorshift32 generators per lane, stepping on a fixed schedule: ``ga.xorshift``.
A rate is a threshold on a 16-bit field of one word: the event happens when the field is below it.

One pass (a generation: breed, then evaluate)
---------------------------------------------
Child ``i`` is bred and evaluated by lane ``i % lanes`` in slot ``i // lanes``.

- The first pass after the population is written (no scores yet) copies every individual
  unchanged: child ``i`` = individual ``i``; it only evaluates.
- Every later pass breeds from the previous pass's population and scores. Child 0 is the elite:
  the first individual of highest score, copied unchanged. Every other child: parent ``a`` and
  parent ``b`` by tournament (T contestants each, drawn uniformly with replacement: index =
  (16-bit field * P) >> 16; the first drawn of the highest score wins), a crossover decision
  (``SEL`` field < ``cross_threshold``), then row by row (row r from ``b`` when crossing and bit 0
  of ``ROW0`` is set, else from ``a``): the DNF-aware mutations of ``ga.operators`` in one row each,
  in the host GA's order:
    1. literal: with ``literal_threshold`` (8 x the per-literal rate: one event per row at most),
       literal field ``(ROW0 >> 1) & 7`` moves to another legal value: don't-care -> x_i
       (``ROW0`` bit 4 = 0) or NOT x_i; a connected literal -> don't-care when the byte
       ``ROW0[8:16]`` < ``to_dc_threshold`` (the host's ratio (1 - p)/(1 - p/2)), else to the
       opposite literal; a contradiction -> don't-care;
    2. output: with ``output_threshold`` (3 x the per-bit rate), output bit ``(ROW1[0:8] * 3) >> 8``
       flips;
    3. switch: with ``switch_threshold``, an on row goes off (outputs cleared, literals kept), an
       off row on with outputs ``((ROW2[0:8] * 7) >> 8) + 1``;
    4. replace: with ``replace_threshold`` (``ROW3`` field), the row becomes a fresh on term
       (``ga.operators.random_rows`` with off_p = 0): literal i is connected when byte i of
       ``ROW4`` (i < 4) or ``ROW5`` (i >= 4) is below ``connect_threshold`` (literal_p), as x_i
       when bit 8 + i of ``ROW3`` is 0, else NOT x_i; outputs ``((ROW3[0:8] * 7) >> 8) + 1``.
- Every child is evaluated on the world model (``ga.evaluator``: the counts are the evaluator
  board's), its fail count F with the board's failure-rate codes (``ga.fail_rates``: the engine
  holds a rate RAM per lane, ``PRIOR_CODE`` everywhere after reset or CLEAR), and scored with
  :func:`score`.

The escape (the on-line run's download after a time-out or loop, ``cosim.online.run``): given a
blamed (state, motion) with an obstacle bit in the state, the engine also tracks the first child
of highest score whose array motion in that state (``ga.operators.motion_in_state``: the rows are
checked one per cycle as they stream into the lane) differs from the blamed motion; `learn`
returns that child when there is one.

Fitness as an integer
---------------------
``score = 5 D (N - crashes) + 4 D (N - loops) + distance - F`` with D = max dist[a] = 50 mm, which
is exactly 10 D N times the fitness 0.5 (1 - c/N) + 0.4 (1 - l/N) + 0.1 d / (N D) - W_FAIL F /
(N RATE_ONE) (``ga.evaluator.fitness``; RATE_ONE = 10 W_FAIL D makes the last term F): the same
order as the exact (rational) fitness, with no division and no float. The score is signed (F up
to RATE_ONE N can exceed the rest: -64,000..128,000 for N <= 256, ``SCORE_BITS`` = 18 bits, and
the hardware compares signed). With the codes of a cleared board (no ``--fail-rates``) F is
``PRIOR_CODE`` times the obstacle states of the model, the same for every child of a pass: the
selection is that of the three SPEC terms.
The float fitness of ``ga.evaluator.fitness`` orders the same way except between exactly equal
fitnesses, whose floats may differ in the last bit (e.g. 4 more crashes and 5 fewer loops); the
hardware treats those as ties, and a tie goes to the lower index (elite) or the first drawn
(tournament). `tests/test_hardware_ga.py` checks both statements.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ga.evaluator import EvalResult, evaluate_population
from ga.fail_rates import RATE_ONE, prior_codes
from ga.genome import LITERAL_MASK, N_ROWS, OUTPUT_MASK, OUTPUT_SHIFT, ROW_DTYPE, validate_rows
from ga.motions import DEFAULT_DISTANCE_RULE, MAX_MOTION_DISTANCE_MM, N_STATES, OBSTACLE_MASK
from ga.operators import CONTRADICTION, DEFAULT_LITERAL_P, DONT_CARE, NEGATIVE, POSITIVE, row_fires, row_outputs
from ga.world_model import WorldModel
from ga.xorshift import (  # noqa: F401  (the random source; re-exported for hdl.learner*, tests)
    GENERATORS,
    MASK32,
    ROW0,
    ROW1,
    ROW2,
    ROW3,
    ROW4,
    ROW5,
    ROW_GENERATORS,
    SEED_FALLBACK,
    SEL,
    lane_seeds,
    seed_salt,
    xorshift32,
    xorshift_stream,
)

# Fields of the words (one word per generator per draw): the HDL slices the same bits.
FIELD16_SHIFT = 16  # bits 16..31: the 16-bit field compared with a threshold / scaled to an index
TAKE_B_BIT = 0  # ROW0
LITERAL_INDEX_SHIFT = 1  # ROW0 bits 1..3
POLARITY_BIT = 4  # ROW0
TO_DC_SHIFT = 8  # ROW0 bits 8..15
CHOICE_MASK = 0xFF  # ROW1, ROW2, ROW3 bits 0..7
FRESH_POLARITY_SHIFT = 8  # ROW3 bits 8..15: polarity of fresh literal i (0: x_i)
SCORE_BITS = 18  # signed: -RATE_ONE N <= score <= 10 D N (module docstring)
STATE_FORMAT = 1  # of HardwareGA.state_dict
# The lanes of the ulx3s-learner bitstream (hdl.fpga; docs/learner.md, "Resources and clock": the
# lanes that fit 80 % of the LFE5U-85F's LUTs and route). The default of HardwareGAConfig and of the
# on-line run's --lanes, so that `--ga hardware` on the reference is the board's lifetime: a lane
# count changes the children's random streams (child i is bred by lane i % lanes).
LEARNER_LANES = 7
assert 10 * MAX_MOTION_DISTANCE_MM * N_STATES < 1 << (SCORE_BITS - 1) and RATE_ONE * N_STATES <= 1 << (SCORE_BITS - 1)


# -- parameters --------------------------------------------------------------------------------------


def _threshold(rate: float, scale: int, name: str) -> int:
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"{name} must be in [0, 1], got {rate!r}")
    return int(round(rate * scale))


@dataclass(frozen=True)
class HardwareGAConfig:
    """Parameters of the learning engine. Rates are per site as in ``ga.evolution.GAConfig`` and
    become thresholds on 16-bit (8-bit for ``to_dc``) random fields."""

    population: int = 500
    tournament: int = 20
    lanes: int = LEARNER_LANES
    crossover_rate: float = 0.5
    literal_rate: float = 0.004  # per literal field (8 per row)
    output_rate: float = 0.004  # per output bit (3 per row)
    switch_rate: float = 0.01  # per row
    replace_rate: float = 0.005  # per row: a fresh term
    literal_p: float = DEFAULT_LITERAL_P  # the initial law the literal mutation keeps

    def __post_init__(self):
        for name in ("population", "tournament", "lanes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if self.population < 2:
            raise ValueError(f"the hardware GA needs a population of at least 2, got {self.population!r}")
        if self.population > 1 << 16:
            raise ValueError(f"population must be at most 65536, got {self.population!r}")
        if self.lanes > 48:
            raise ValueError(f"lanes must be at most 48 (fewer than a slot's cycles), got {self.lanes!r}")
        for name in ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate"):
            _threshold(getattr(self, name), 1, name)
        if not 0.0 <= self.literal_p < 1.0:
            raise ValueError(f"literal_p must be in [0, 1), got {self.literal_p!r}")

    @property
    def cross_threshold(self) -> int:
        return _threshold(self.crossover_rate, 1 << 16, "crossover_rate")

    @property
    def literal_threshold(self) -> int:
        return _threshold(min(8 * self.literal_rate, 1.0), 1 << 16, "literal_rate")

    @property
    def output_threshold(self) -> int:
        return _threshold(min(3 * self.output_rate, 1.0), 1 << 16, "output_rate")

    @property
    def switch_threshold(self) -> int:
        return _threshold(self.switch_rate, 1 << 16, "switch_rate")

    @property
    def replace_threshold(self) -> int:
        return _threshold(self.replace_rate, 1 << 16, "replace_rate")

    @property
    def connect_threshold(self) -> int:
        return _threshold(self.literal_p, 1 << 8, "literal_p")

    @property
    def to_dc_threshold(self) -> int:
        p = self.literal_p
        return _threshold((1 - p) / (1 - p / 2), 1 << 8, "to_dc")

    @property
    def slots(self) -> int:
        """Child slots per pass: ceil(population / lanes)."""
        return -(-self.population // self.lanes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


# -- the integer fitness ------------------------------------------------------------------------------


def score(crashes, loops, distance, n_states: int, fails=0) -> np.ndarray:
    """10 D N x the fitness, as integers (int64): 5 D (N - c) + 4 D (N - l) + d - F, F the
    failure-rate count (``ga.fail_rates``: RATE_ONE = 10 W_FAIL D makes its term exactly F).
    Negative when F outweighs the rest (the hardware's score is signed, ``SCORE_BITS``)."""
    d = MAX_MOTION_DISTANCE_MM
    c, l, dist, f = (np.asarray(v, dtype=np.int64) for v in (crashes, loops, distance, fails))
    return 5 * d * (n_states - c) + 4 * d * (n_states - l) + dist - f


def first_best(scores) -> int:
    """Index of the first highest score (the hardware's running best, strict >)."""
    return int(np.argmax(np.asarray(scores)))


# -- cycle count of the engine ---------------------------------------------------------------------


# The engine's pipeline (hdl.learner): a bred row reaches the lane's shadow ROW_LATENCY cycles
# after its draw (the lane's registered bank address, the bank's synchronous read, the banks'
# registered group multiplexer); a finished evaluation reaches the running best and the score
# replicas RESULT_LATENCY cycles after the evaluator's done (the lanes' registered result bus).
ROW_LATENCY = 3
RESULT_LATENCY = 1


def slot_cycles(n_states: int, tournament: int) -> int:
    """Cycles C of one child slot: selection (2T + 1 draws, one fitness read each) then breeding
    (50 rows, one row-bank read each, ROW_LATENCY cycles from a row's draw to its write into the
    lane's shadow; the last row may be written in the cycle of the start) must fit before the
    start in the slot's last cycle, and the previous evaluation must be over by then (the
    evaluator is ready again N + 2 cycles after the cycle of its start):
    C = max(N + 2, 2T + 1 + 50 + ROW_LATENCY) = max(N + 2, 2T + 54)."""
    return max(n_states + 2, 2 * tournament + 1 + N_ROWS + ROW_LATENCY)


def pass_cycles(n_states: int, config: HardwareGAConfig) -> int:
    """Clock cycles of one pass of ``hdl.learner.Learner``: ``config.slots`` slots of breeding
    (slot s's children evaluate during slot s + 1), one more slot for the last evaluations, and
    the lanes' stagger (lane j runs j cycles behind lane 0) and the result bus: L + RESULT_LATENCY
    cycles of drain."""
    return (config.slots + 1) * slot_cycles(n_states, config.tournament) + config.lanes + RESULT_LATENCY


def learn_cycles(n_states: int, config: HardwareGAConfig, generations: int) -> int:
    """Clock edges of ``learn(generations)`` from the edge that samples the start strobe to the
    one that raises done: the passes and one edge to leave Idle."""
    return 1 + generations * pass_cycles(n_states, config)


# -- the GA -----------------------------------------------------------------------------------------------


def _mutate_rows(words, r0, r1, r2, r3, r4, r5, config: HardwareGAConfig):
    """The four row mutations of the module docstring on row words (any shape, uint32)."""
    f16 = np.uint32(FIELD16_SHIFT)
    # Most rows have no event (about 6 % have one at the default rates): the datapath below runs
    # on those that do; a row without an event comes out unchanged.
    touched = np.flatnonzero(((r0 >> f16) < config.literal_threshold)
                             | ((r1 >> f16) < config.output_threshold)
                             | ((r2 >> f16) < config.switch_threshold)
                             | ((r3 >> f16) < config.replace_threshold))
    out = np.asarray(words).astype(ROW_DTYPE).ravel()
    if touched.size:
        out[touched] = _mutate_datapath(*(np.asarray(v).ravel()[touched] for v in (words, r0, r1, r2, r3, r4, r5)),
                                        config)
    return out.reshape(np.shape(words))


def _mutate_datapath(words, r0, r1, r2, r3, r4, r5, config: HardwareGAConfig):
    """The row mutation datapath on every row given (what each lane computes on every row)."""
    w = words.astype(np.uint32, copy=True)
    u32 = np.uint32
    # 1. literal
    lit_event = (r0 >> u32(FIELD16_SHIFT)) < config.literal_threshold
    shift = ((r0 >> u32(LITERAL_INDEX_SHIFT)) & u32(7)) * u32(2)
    old = (w >> shift) & u32(3)
    polarity = (r0 >> u32(POLARITY_BIT)) & u32(1)
    to_dc = ((r0 >> u32(TO_DC_SHIFT)) & u32(0xFF)) < config.to_dc_threshold
    new = np.where(old == DONT_CARE, np.where(polarity == 0, POSITIVE, NEGATIVE),
                   np.where(old == CONTRADICTION, DONT_CARE,
                            np.where(to_dc, DONT_CARE, np.where(old == POSITIVE, NEGATIVE, POSITIVE))))
    w = np.where(lit_event, (w & ~(u32(3) << shift)) | (new.astype(np.uint32) << shift), w)
    # 2. output bit
    out_event = (r1 >> u32(FIELD16_SHIFT)) < config.output_threshold
    bit = ((r1 & u32(CHOICE_MASK)) * u32(3)) >> u32(8)
    w = np.where(out_event, w ^ (u32(1) << (u32(OUTPUT_SHIFT) + bit)), w)
    # 3. row switch
    sw_event = (r2 >> u32(FIELD16_SHIFT)) < config.switch_threshold
    code = (((r2 & u32(CHOICE_MASK)) * u32(7)) >> u32(8)) + u32(1)
    literals = w & u32(LITERAL_MASK)
    on = (w & u32(OUTPUT_MASK)) != 0
    w = np.where(sw_event, np.where(on, literals, literals | (code << u32(OUTPUT_SHIFT))), w)
    # 4. row replacement by a fresh on term
    rep_event = (r3 >> u32(FIELD16_SHIFT)) < config.replace_threshold
    fresh = ((((r3 & u32(CHOICE_MASK)) * u32(7)) >> u32(8)) + u32(1)) << u32(OUTPUT_SHIFT)
    for i in range(8):
        source = r4 if i < 4 else r5
        connected = ((source >> u32(8 * (i % 4))) & u32(0xFF)) < config.connect_threshold
        negative = (r3 >> u32(FRESH_POLARITY_SHIFT + i)) & u32(1)
        fresh = fresh | np.where(connected, (u32(POSITIVE) + negative) << u32(2 * i), u32(0))
    w = np.where(rep_event, fresh, w)
    return w.astype(ROW_DTYPE)


class HardwareGA:
    """The engine's state and its passes: population (P, 50), the last pass's scores (None until
    a pass has run on this population) and the generator states (lanes, 4).

    ``learn(model, generations)`` runs that many passes (the first after `load_population` only
    evaluates) and returns the best of the last pass with its counts."""

    def __init__(self, config: HardwareGAConfig, seed: int, population):
        self.config = config
        self.seed = int(seed)
        self.generators = lane_seeds(self.seed, config.lanes)
        self.load_population(population)
        self.passes = 0
        self.cycles = 0

    escape_index: int | None = None  # the escape child of the last pass (learn's avoid)

    def load_population(self, population) -> None:
        pop = validate_rows(population)
        if pop.shape != (self.config.population, N_ROWS):
            raise ValueError(f"expected a population of shape ({self.config.population}, {N_ROWS}), "
                             f"got {pop.shape!r}")
        self.population = pop.copy()
        self.scores: np.ndarray | None = None
        self.counts: EvalResult | None = None

    def _draws(self):
        cfg = self.config
        sel, self.generators[:, SEL] = xorshift_stream(
            self.generators[:, SEL], cfg.slots * (2 * cfg.tournament + 1))
        rows, self.generators[:, ROW0:] = xorshift_stream(self.generators[:, ROW0:], cfg.slots * N_ROWS)
        sel = sel.reshape(cfg.lanes, cfg.slots, 2 * cfg.tournament + 1)
        rows = rows.reshape(cfg.lanes, len(ROW_GENERATORS), cfg.slots, N_ROWS)
        # lane-major (lane, slot) -> child order (slot, lane)
        return sel.transpose(1, 0, 2).reshape(-1, sel.shape[-1]), rows.transpose(2, 0, 1, 3).reshape(
            -1, len(ROW_GENERATORS), N_ROWS)

    def breed(self) -> np.ndarray:
        """The children of one pass (P, 50), drawing this pass's random words."""
        cfg = self.config
        P, T = cfg.population, cfg.tournament
        sel, rows = self._draws()
        sel, rows = sel[:P], rows[:P]
        pop = self.population
        if self.scores is None:
            return pop.copy()
        contestants = ((sel[:, :2 * T] >> np.uint32(FIELD16_SHIFT)).astype(np.int64) * P) >> 16
        fit = self.scores[contestants]
        a = contestants[np.arange(P), np.argmax(fit[:, :T], axis=1)]
        b = contestants[np.arange(P), T + np.argmax(fit[:, T:], axis=1)]
        cross = (sel[:, 2 * T] >> np.uint32(FIELD16_SHIFT)) < cfg.cross_threshold
        r0 = rows[:, 0]
        take_b = cross[:, None] & ((r0 >> np.uint32(TAKE_B_BIT)) & np.uint32(1) == 1)
        base = np.where(take_b, pop[b], pop[a])
        children = _mutate_rows(base, *(rows[:, k] for k in range(len(ROW_GENERATORS))), cfg)
        children[0] = pop[first_best(self.scores)]  # the elite
        return children

    def run_pass(self, model: WorldModel, reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE,
                 avoid: tuple[int, int] | None = None, rates=None) -> None:
        """One pass; ``rates``: the board's failure-rate codes (256, 8), None for a cleared
        board's (``PRIOR_CODE`` everywhere, the engine after reset)."""
        children = self.breed()
        counts = evaluate_population(children, model, reflex=reflex, distance_rule=distance_rule,
                                     rates=prior_codes() if rates is None else rates)
        self.population = children
        self.counts = counts
        self.scores = score(counts.crashes, counts.loops, counts.distance, model.n_states, counts.fails)
        self.escape_index = None
        if avoid is not None:
            state, motion = avoid
            motions = np.bitwise_or.reduce(np.where(row_fires(children, state), row_outputs(children), 0), axis=-1)
            eligible = motions != motion  # the array's motion in the state (truth_tables, reflex=False)
            if eligible.any():
                self.escape_index = int(np.flatnonzero(eligible)[np.argmax(self.scores[eligible])])
        self.passes += 1
        self.cycles += pass_cycles(model.n_states, self.config)

    def learn(self, model: WorldModel, generations: int, reflex: bool = True,
              distance_rule: str = DEFAULT_DISTANCE_RULE, avoid: tuple[int, int] | None = None, rates=None):
        """``generations`` passes on ``model`` (and the rate codes ``rates``: see `run_pass`).
        Returns (the download (50,), its (crashes, loops, distance), the cycles the engine
        takes); its fail count is ``counts.fails[download_index]``. The download is the best of
        the last pass, or with ``avoid`` = (state, motion) (an obstacle state) the escape child if
        there is one."""
        if isinstance(generations, bool) or not isinstance(generations, int) or generations < 1:
            raise ValueError(f"generations must be a positive integer, got {generations!r}")
        if avoid is not None and not (int(avoid[0]) & OBSTACLE_MASK):
            raise ValueError(f"the escape needs a state with an obstacle bit, got {avoid!r}")
        for g in range(generations):  # only the last pass's escape child is read
            self.run_pass(model, reflex, distance_rule, avoid if g == generations - 1 else None, rates)
        self.cycles += 1
        index = self.download_index
        return (self.population[index].copy(), self.counts.row(index),
                learn_cycles(model.n_states, self.config, generations))

    def state_dict(self) -> dict:
        """Everything a later pass depends on, as JSON values (the engine between two learns):
        population, scores and counts of the last pass, generator states, counters."""
        counts = self.counts
        return {
            "format": STATE_FORMAT, "config": self.config.to_dict(), "seed": self.seed,
            "population": self.population.astype("<u4").tobytes().hex(),
            "scores": None if self.scores is None else self.scores.tolist(),
            "counts": None if counts is None else [counts.crashes.tolist(), counts.loops.tolist(),
                                                   counts.distance.tolist(), counts.fails.tolist()],
            "generators": self.generators.tolist(), "passes": self.passes, "cycles": self.cycles,
            "escape_index": self.escape_index,
        }

    @classmethod
    def from_state_dict(cls, d: dict) -> "HardwareGA":
        """The engine of ``state_dict`` output: its next pass is the saved engine's next pass."""
        if d.get("format") != STATE_FORMAT:
            raise ValueError(f"hardware GA state format {d.get('format')!r} is not {STATE_FORMAT}")
        config = HardwareGAConfig(**d["config"])
        population = np.frombuffer(bytes.fromhex(d["population"]), dtype="<u4").reshape(-1, N_ROWS)
        ga = cls(config, d["seed"], population.astype(ROW_DTYPE))
        generators = np.asarray(d["generators"], dtype=np.uint32)
        if generators.shape != ga.generators.shape:
            raise ValueError(f"hardware GA state has generators of shape {generators.shape!r}, "
                             f"expected {ga.generators.shape!r}")
        ga.generators = generators
        if d["scores"] is not None:
            ga.scores = np.asarray(d["scores"], dtype=np.int64)
            ga.counts = EvalResult(*(np.asarray(c, dtype=np.int64) for c in d["counts"]))
        ga.passes, ga.cycles, ga.escape_index = int(d["passes"]), int(d["cycles"]), d["escape_index"]
        return ga

    @property
    def download_index(self) -> int:
        """The escape child of the last pass if there is one, else its best."""
        escape = getattr(self, "escape_index", None)
        return self.best_index if escape is None else escape

    @property
    def best_index(self) -> int:
        if self.scores is None:
            raise ValueError("no pass has run on this population yet")
        return first_best(self.scores)

    def best(self) -> np.ndarray:
        return self.population[self.best_index].copy()

    def best_counts(self) -> tuple[int, int, int]:
        return self.counts.row(self.best_index)


def learn(world_model: WorldModel, population, generations: int, seed: int,
          config: HardwareGAConfig | None = None, reflex: bool = True,
          distance_rule: str = DEFAULT_DISTANCE_RULE, avoid: tuple[int, int] | None = None, rates=None):
    """One learning phase from scratch: a fresh engine seeded with ``seed`` holding
    ``population`` (its first pass only evaluates), with the rate codes ``rates`` (None: a
    cleared board's). Returns (best rows, the last population, counts (crashes, loops, distance)
    of the best; with ``avoid``, of the escape child)."""
    pop = validate_rows(population)
    config = config or HardwareGAConfig(population=pop.shape[0])
    ga = HardwareGA(config, seed, pop)
    best, counts, _ = ga.learn(world_model, generations, reflex, distance_rule, avoid, rates)
    return best, ga.population.copy(), counts
