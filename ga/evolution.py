"""An ask/tell genetic algorithm over populations of 50-term DNF genomes (rows form).

The GA never evaluates anything itself: ``ask()`` hands out the population to evaluate and
``tell(fitness)`` takes the fitness vector back and breeds the next generation. The caller decides
how fitness is computed (serial, a process pool, the evaluator HDL), so the GA is the same in the
off-line and on-line experiments.

One generation (`tell`):
1. the ``elitism`` fittest individuals are copied unchanged to the head of the next population
   (the paper's "elitist strategy to maintain the best individual");
2. every other child: two parents by tournament selection (size ``tournament``); with probability
   ``crossover_rate`` a row-aligned crossover of the two, otherwise a copy of the first; then the
   per-site mutations of `ga.operators.mutate`.

All randomness comes from the one ``numpy.random.Generator`` given to the constructor; its state is
part of `state_dict`, so a run restored with `from_state_dict` continues bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ga import operators
from ga.genome import ROW_DTYPE, hex_from_rows, rows_from_hex, validate_rows
from ga.motions import REFLEX_TABLE

STATE_FORMAT = 1  # bump when the layout of state_dict changes


@dataclass(frozen=True)
class GAConfig:
    """Parameters of the GA. Rates are per site (per literal field, per output bit, per row).

    Defaults are the off-line experiment's (paper section 5.1: population 20, tournament 5,
    elitism); the mutation rates were chosen on the measurements in docs/offline.md.
    """

    population: int = 20
    tournament: int = 5
    elitism: int = 1
    crossover_rate: float = 0.5
    crossover: str = "uniform"  # a key of ga.operators.CROSSOVERS
    literal_rate: float = 0.004  # per literal field: 400 per genome -> 1.6 per child
    output_rate: float = 0.004  # per output bit: 150 per genome -> 0.6 per child
    switch_rate: float = 0.01  # per row: 0.5 per child
    replace_rate: float = 0.005  # per row: a fresh random term, 0.25 per child
    # Per child: if its first parent reported a failure state (tell(..., failures=)), change the
    # child's motion there (ga.operators.avoid_state_motion). 0 = the plain GA.
    directed_rate: float = 0.0
    directed_literals: int = 6  # literals of the term the directed mutation writes (8: s alone)
    literal_p: float = operators.DEFAULT_LITERAL_P  # connected-literal probability of new terms
    off_p: float = operators.DEFAULT_OFF_P  # fraction of off rows in the initial population

    def __post_init__(self):
        if self.population < 1:
            raise ValueError(f"population must be at least 1, got {self.population!r}")
        if self.tournament < 1:
            raise ValueError(f"tournament must be at least 1, got {self.tournament!r}")
        if not 0 <= self.elitism <= self.population:
            raise ValueError(f"elitism must be in 0..population, got {self.elitism!r}")
        if self.crossover not in operators.CROSSOVERS:
            raise ValueError(
                f"crossover must be one of {sorted(operators.CROSSOVERS)}, got {self.crossover!r}"
            )
        for name in ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate",
                     "directed_rate", "literal_p", "off_p"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {value!r}")
        if not 1 <= self.directed_literals <= 8:
            raise ValueError(f"directed_literals must be in 1..8, got {self.directed_literals!r}")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


class GeneticAlgorithm:
    """Ask/tell GA. ``initial`` (optional, (Q, 50) rows, Q <= population) seeds the first population;
    the remaining individuals are drawn by `ga.operators.random_population`."""

    def __init__(self, config: GAConfig, rng: np.random.Generator, initial=None):
        self.config = config
        self.rng = rng
        pop = operators.random_population(rng, config.population, config.literal_p, config.off_p)
        if initial is not None:
            initial = validate_rows(initial)
            initial = initial[None] if initial.ndim == 1 else initial
            if len(initial) > config.population:
                raise ValueError(
                    f"{len(initial)} initial genomes do not fit a population of {config.population}"
                )
            pop[: len(initial)] = initial
        self._population = pop
        self.generation = 0  # generations evaluated so far (tell() calls)
        self.best_rows: np.ndarray | None = None
        self.best_fitness: float = float("-inf")
        self.last_fitness: np.ndarray | None = None

    # -- ask / tell --------------------------------------------------------------------------

    def ask(self) -> np.ndarray:
        """The population to evaluate now: (population, 50) uint32 (a copy)."""
        return self._population.copy()

    def tell(self, fitness, failures=None) -> None:
        """Take the fitness of the population given by `ask` and breed the next generation.

        ``failures`` (optional, one per individual): the world state where the individual failed
        (crashed or got stuck), or None; used by the directed mutation (``directed_rate``).
        ``best_rows`` / ``best_fitness`` become the best of this evaluated generation (with
        elitism and a deterministic fitness, also the best ever).
        """
        cfg = self.config
        fitness = np.asarray(fitness, dtype=float)
        if fitness.shape != (cfg.population,):
            raise ValueError(f"expected {cfg.population} fitness values, got shape {fitness.shape!r}")
        if not np.isfinite(fitness).all():
            raise ValueError(f"fitness must be finite, got {fitness[~np.isfinite(fitness)][:3]!r}")
        if failures is not None and len(failures) != cfg.population:
            raise ValueError(f"expected {cfg.population} failure states, got {len(failures)!r}")
        pop = self._population
        order = operators.elite(fitness, max(cfg.elitism, 1))
        self.best_rows = pop[order[0]].copy()
        self.best_fitness = float(fitness[order[0]])
        self.last_fitness = fitness.copy()
        self._population = self.breed(pop, fitness, failures)
        self.generation += 1

    def breed(self, pop: np.ndarray, fitness: np.ndarray, failures=None) -> np.ndarray:
        """The next population from an evaluated one (elites first, then the offspring)."""
        cfg = self.config
        rng = self.rng
        elites = pop[operators.elite(fitness, cfg.elitism)]
        n = cfg.population - cfg.elitism
        if n == 0:
            return elites.copy()
        parents = operators.tournament(rng, fitness, 2 * n, cfg.tournament).reshape(n, 2)
        a, b = pop[parents[:, 0]], pop[parents[:, 1]]
        crossed = operators.CROSSOVERS[cfg.crossover](rng, a, b)
        do_cross = rng.random(n) < cfg.crossover_rate
        children = np.where(do_cross[:, None], crossed, a)
        children = operators.mutate(
            rng, children, cfg.literal_rate, cfg.output_rate, cfg.switch_rate, cfg.replace_rate,
            cfg.literal_p,
        )
        if failures is not None and cfg.directed_rate > 0:
            directed = rng.random(n) < cfg.directed_rate
            for i in np.flatnonzero(directed):
                state = failures[parents[i, 0]]
                # The reflex fixes the motion of obstacle-free states: the array cannot change it.
                if state is not None and REFLEX_TABLE[int(state)] < 0:
                    children[i] = operators.avoid_state_motion(
                        rng, children[i], int(state), cfg.directed_literals
                    )
        return np.concatenate([elites, children]).astype(ROW_DTYPE)

    # -- checkpoints ---------------------------------------------------------------------------

    def state_dict(self) -> dict:
        """Everything needed to continue bit for bit, as JSON-able Python values."""
        return {
            "format": STATE_FORMAT,
            "config": self.config.to_dict(),
            "generation": self.generation,
            "population": [hex_from_rows(g) for g in self._population],
            "best_rows": None if self.best_rows is None else hex_from_rows(self.best_rows),
            "best_fitness": self.best_fitness if self.best_rows is not None else None,
            "last_fitness": None if self.last_fitness is None else [float(f) for f in self.last_fitness],
            "rng": self.rng.bit_generator.state,
        }

    @classmethod
    def from_state_dict(cls, d: dict, rng: np.random.Generator | None = None) -> "GeneticAlgorithm":
        """Rebuild a GA from `state_dict` output. ``rng`` (default a fresh PCG64 generator) gets
        the saved bit-generator state, so its stream continues where the saved one stopped."""
        if d.get("format") != STATE_FORMAT:
            raise ValueError(f"GA state format {d.get('format')!r} is not {STATE_FORMAT}")
        rng = np.random.default_rng() if rng is None else rng
        saved = d["rng"]
        if saved.get("bit_generator") != type(rng.bit_generator).__name__:
            raise ValueError(
                f"GA state uses bit generator {saved.get('bit_generator')!r}, "
                f"the given rng is {type(rng.bit_generator).__name__!r}"
            )
        rng.bit_generator.state = saved
        ga = cls.__new__(cls)
        ga.config = GAConfig(**d["config"])
        ga.rng = rng
        ga._population = np.stack([rows_from_hex(h) for h in d["population"]]).astype(ROW_DTYPE)
        ga.generation = int(d["generation"])
        ga.best_rows = None if d["best_rows"] is None else rows_from_hex(d["best_rows"])
        ga.best_fitness = float("-inf") if d["best_fitness"] is None else float(d["best_fitness"])
        ga.last_fitness = None if d["last_fitness"] is None else np.array(d["last_fitness"], dtype=float)
        return ga
