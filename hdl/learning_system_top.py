"""The learning system top: the system top's controller board beside the learning engine.

The top of the cocotb learning board (``cosim.boards.cocotb_learning``, ``--ga hardware`` on the
Verilog): one ``hdl.system_top.SystemTop`` (its ports unchanged, so ``SystemHost`` drives the
controller EHW as on the system top; its evaluator stays unused, the engine replaces it) and one
``hdl.learner.Learner`` whose ports are the top's ports prefixed ``lrn_`` (``lrn_model__state``,
``lrn_start``, ``lrn_best_index``, ...). Nothing else: the two blocks share only the clock.

:class:`LearnerHost` is the host side of the engine's ports over any *pins* object
(``hdl.ports``: ``AmaranthPins`` on a bare ``Learner`` with ``prefix=""``, ``CocotbPins`` on this
top): the one driver of the Amaranth and cocotb learning boards, so both spend the same cycles.
"""

from __future__ import annotations

from amaranth.hdl import Module
from amaranth.lib import wiring

from ga import hardware_ga as hg
from ga.genome import N_ROWS
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.learner import Learner
from hdl.system_top import P_MAX, SystemTop

PREFIX = "lrn_"
# The engine's inputs (the Learner's In ports, as in the generated Verilog).
LEARNER_INPUTS = ("pop_index", "pop_row", "pop_data", "pop_we", "seed", "seed_we", "generations", "start",
                  "model__state", "model__motion", "model__next", "model__crash", "model__valid",
                  "model__we", "rate__state", "rate__motion", "rate__code", "rate__we", "state_value",
                  "state_we", "clear", "reflex_en", "avoid_en", "avoid_state", "avoid_motion")


def _resolve(obj, path):
    for part in path:
        obj = obj[part] if isinstance(part, int) else getattr(obj, part)
    return obj


class LearningSystemTop(wiring.Component):
    """``SystemTop`` (same ports) + ``Learner`` (ports prefixed ``lrn_``).

    Parameters
    ----------
    config : ga.hardware_ga.HardwareGAConfig
        The engine's parameters (constants of the circuit).
    p_max : int
        The system top's population RAM depth (its evaluator is not used here).
    distance_rule : str
        dist[a] of every evaluator (``ga.motions.DISTANCE_RULES``).
    """

    def __init__(self, config: hg.HardwareGAConfig, p_max: int = P_MAX,
                 distance_rule: str = DEFAULT_DISTANCE_RULE):
        self.system = SystemTop(p_max=p_max, distance_rule=distance_rule)
        self.learner = Learner(config, distance_rule)
        members = dict(self.system.signature.members.items())
        members.update({PREFIX + name: member for name, member in self.learner.signature.members.items()})
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        m.submodules.system = self.system
        m.submodules.learner = self.learner
        for sub, prefix in ((self.system, ""), (self.learner, PREFIX)):
            for path, member, inner in sub.signature.flatten(sub):
                outer = _resolve(self, (prefix + path[0], *path[1:]))
                if member.flow == wiring.In:
                    m.d.comb += inner.eq(outer)
                else:
                    m.d.comb += outer.eq(inner)
        return m


class LearnerHost:
    """The engine's host protocol (``hdl.learner``'s module docstring) as coroutines over pins.

    Inputs are set before ``tick``; the edge samples them; outputs are read after it. The names
    are the ``Learner``'s ports with ``prefix`` in front."""

    def __init__(self, pins, prefix: str = PREFIX):
        self.pins, self.prefix = pins, prefix

    def set(self, name: str, value) -> None:
        self.pins.set(self.prefix + name, int(value))

    def get(self, name: str) -> int:
        return self.pins.get(self.prefix + name)

    async def wait_ready(self) -> None:
        """Until the lanes have swept their world-model RAMs (after reset)."""
        while not self.get("ready"):
            await self.pins.tick()

    async def seed(self, seed: int) -> None:
        self.set("seed", seed)
        self.set("seed_we", 1)
        await self.pins.tick()
        self.set("seed_we", 0)

    async def write_population(self, population) -> None:
        """Every row of every individual, one a cycle (the next learn's first pass only evaluates)."""
        for i, genome in enumerate(population):
            for r, word in enumerate(genome):
                self.set("pop_index", i)
                self.set("pop_row", r)
                self.set("pop_data", word)
                self.set("pop_we", 1)
                await self.pins.tick()
        self.set("pop_we", 0)

    async def observe(self, model, state, motion, next_state, crashed) -> None:
        """Apply one observation to the host's mirror ``model`` (``ga.world_model``) and write the
        resulting entry and both states to every lane: 2 cycles."""
        model.observe(state, motion, next_state, crashed)
        for name, value in (("state", state), ("motion", motion), ("next", model.next_state[state, motion]),
                            ("crash", model.crash[state, motion]), ("valid", 1), ("we", 1)):
            self.set(f"model__{name}", value)
        self.set("state_value", state)
        self.set("state_we", 1)
        await self.pins.tick()
        self.set("model__we", 0)
        self.set("state_value", next_state)
        await self.pins.tick()
        self.set("state_we", 0)

    async def write_rates(self, changes) -> None:
        """Failure-rate codes (``ga.fail_rates``): one (state, motion, code) a cycle, to every lane."""
        for state, motion, code in changes:
            for name, value in (("state", state), ("motion", motion), ("code", code), ("we", 1)):
                self.set(f"rate__{name}", value)
            await self.pins.tick()
        self.set("rate__we", 0)

    async def read_genome(self, index: int) -> list[int]:
        rows = []
        for r in range(N_ROWS):  # the edge samples the address; the data is there after it
            self.set("pop_index", index)
            self.set("pop_row", r)
            await self.pins.tick()
            rows.append(self.get("pop_rdata"))
        return rows

    async def learn(self, generations: int, reflex: bool = True, avoid=None):
        """Run ``generations`` passes; one wait for ``done`` (no Python per cycle under cocotb).
        Returns (download index, (crashes, loops, distance), fails, score (signed), the ``cycles``
        register, escaped): the download is the escape child when ``avoid`` = (state, motion) is
        given and one exists (``escaped``: it is not the best), else the best."""
        self.set("reflex_en", reflex)
        self.set("avoid_en", avoid is not None)
        if avoid is not None:
            self.set("avoid_state", avoid[0])
            self.set("avoid_motion", avoid[1])
        self.set("generations", generations)
        self.set("start", 1)
        await self.pins.tick()
        self.set("start", 0)
        await self.pins.wait(self.prefix + "done")
        kind = "escape" if avoid is not None and self.get("escape_found") else "best"
        index = self.get(f"{kind}_index")
        counts = tuple(self.get(f"{kind}_{name}") for name in ("crashes", "loops", "distance"))
        escaped = kind == "escape" and index != self.get("best_index")
        score = self.get(f"{kind}_score")
        if score >= 1 << (hg.SCORE_BITS - 1):  # cocotb's pins read the raw two's complement bits
            score -= 1 << hg.SCORE_BITS
        return index, counts, self.get(f"{kind}_fails"), score, self.get("cycles"), escaped
