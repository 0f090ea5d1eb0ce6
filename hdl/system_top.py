"""Both EHW boards in one top, plus a population streamer: the HDL side of the co-simulation.

``SystemTop`` is what the HDL backends of ``cosim.boards.registry`` drive (``cosim.hdl_host``): in
Amaranth's simulator (``--backend amaranth``) and, converted to Verilog (``system_top.v``), in
Icarus under cocotb (``--backend cocotb``). It holds

- ``ctl``: the robot's board, ``hdl.controller_ehw.ControllerEHW``, its ports brought out with a
  ``ctl_`` prefix (row-write port, commit, sensor bits in, registered motion out);
- ``ev``: the evaluator board, ``hdl.evaluator_ehw.EvaluatorEHW``: its world-model write port,
  failure-rate write port, state port, clear and reflex enable brought out with an ``ev_`` prefix;
  its row-write port and start/done handshake are driven by
- the population streamer: a population RAM of ``p_max`` controllers (one 950-bit genome per
  word, written by the host through ``pop_we``/``pop_addr``/``pop_data``), and a results RAM
  (``res_addr`` -> ``res_data``). A ``go`` pulse streams controllers 0..``pop_size``-1 through
  the evaluator: the 50 rows of controller i + 1 are written into the evaluator's shadow while
  controller i is evaluated, ``start`` is raised as soon as the evaluator is ready and the rows
  are in, and each ``done`` stores (crashes, loops, distance, fails) at the controller's index. After
  the last one, ``pop_done`` pulses and ``pop_cycles`` holds the cycles from ``go`` to it.

Why the streamer: the host (Python) must stay out of the per-cycle path. Started one controller at
a time, each evaluation costs the host 50 row writes plus a start/done wait, i.e. ~50 awaited
clock edges; with the streamer a population costs P writes, one wait and P reads (see
docs/hdl_in_the_loop.md for the measurements). The evaluator itself is unchanged and still loaded
through its row-write port, one row per cycle, overlapped with evaluating the previous controller.

Timing (``sync`` domain, synchronous reset; inputs sampled at the rising edge ending cycle t):

- ``pop_we`` in cycle t writes ``pop_data`` at address ``pop_addr`` at the end of cycle t
  (ignored while ``pop_busy``).
- ``go`` in cycle t (with ``pop_size`` = P, 1 <= P <= p_max, while not ``pop_busy``) starts the
  stream; ``pop_busy`` is high from cycle t + 1 until the cycle in which ``pop_done`` is high.
  A population of P controllers on a model of N states costs about P * max(N + 2, 51) + 50
  cycles (``pop_cycles``).
- ``res_addr`` in cycle t gives ``res_data`` in cycle t + 1 (synchronous read): a word of
  ``hdl.ports.RESULT_LAYOUT`` (crashes, loops, distance, fails, as the evaluator's result registers).
- World-model, rate and state writes (``ev_model``, ``ev_rate``, ``ev_state_*``) and ``ev_clear``
  go straight to the evaluator: only while it is ``ev_ready`` and no stream runs. After reset the
  evaluator sweeps its RAMs (2049 cycles): wait for ``ev_ready``.
"""

from __future__ import annotations

from amaranth.hdl import Array, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ga.genome import GENOME_BITS, N_ROWS, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE, N_INPUTS, N_OUTPUTS
from hdl.and_or_array import _check_positive
from hdl.controller_ehw import ControllerEHW
from hdl.evaluator_ehw import COUNT_BITS, EvaluatorEHW
from hdl.ports import (  # noqa: F401
    RESULT_LAYOUT,
    ModelWriteSignature,
    RateWriteSignature,
    RowWriteSignature,
    unpack_result,
    write_rows,
)

P_MAX = 512  # controllers per stream: the paper's population of 500 fits in one
RESULT_BITS = RESULT_LAYOUT.size  # crashes | loops | distance | fails = 50 bits
POP_CYCLE_BITS = 32


class SystemTop(wiring.Component):
    """Controller EHW + evaluator EHW + population streamer (see the module docstring).

    Parameters
    ----------
    p_max : int
        Depth of the population and results RAMs (default 512).

    Ports
    -----
    ctl_row : In(RowWriteSignature()), ctl_commit : In(1), ctl_x : In(8), ctl_reflex_en : In(1),
    ctl_motion : Out(3)
        The controller board's ports (docs/hdl_controller.md), forwarded to it.
    ev_model : In(ModelWriteSignature()), ev_rate : In(RateWriteSignature()),
    ev_state_value : In(8), ev_state_we : In(1), ev_clear : In(1), ev_reflex_en : In(1)
        The evaluator's world-model port, failure-rate port, state port, clear and reflex enable
        (docs/evaluator.md).
    ev_ready : Out(1), ev_n_states : Out(9)
        The evaluator is idle; |S|.
    pop_addr : In(9), pop_data : In(950), pop_we : In(1)
        Population RAM write port (one genome per word, bit b = genome bit b).
    pop_size : In(10), go : In(1)
        Stream controllers 0..pop_size-1 through the evaluator.
    pop_busy : Out(1), pop_done : Out(1), pop_cycles : Out(32)
        Streaming; one-cycle pulse at the end; cycles from ``go`` to ``pop_done``.
    res_addr : In(9), res_data : Out(RESULT_LAYOUT)
        Results RAM read port (synchronous): a (crashes, loops, distance, fails) word.
    """

    def __init__(self, p_max: int = P_MAX, distance_rule: str = DEFAULT_DISTANCE_RULE):
        self.p_max = _check_positive("p_max", p_max)
        self.distance_rule = distance_rule  # dist[a] of the evaluator (ga.motions.DISTANCE_RULES)
        index = max(1, (p_max - 1).bit_length())
        super().__init__({
            "ctl_row": In(RowWriteSignature(N_ROWS)),
            "ctl_commit": In(1),
            "ctl_x": In(N_INPUTS),
            "ctl_reflex_en": In(1),
            "ctl_motion": Out(N_OUTPUTS),
            "ev_model": In(ModelWriteSignature()),
            "ev_rate": In(RateWriteSignature()),
            "ev_state_value": In(N_INPUTS),
            "ev_state_we": In(1),
            "ev_clear": In(1),
            "ev_reflex_en": In(1),
            "ev_ready": Out(1),
            "ev_n_states": Out(COUNT_BITS),
            "pop_addr": In(index),
            "pop_data": In(GENOME_BITS),
            "pop_we": In(1),
            "pop_size": In(p_max.bit_length()),
            "go": In(1),
            "pop_busy": Out(1),
            "pop_done": Out(1),
            "pop_cycles": Out(POP_CYCLE_BITS),
            "res_addr": In(index),
            "res_data": Out(RESULT_LAYOUT),
        })

    def elaborate(self, platform):
        m = Module()
        ctl = m.submodules.ctl = ControllerEHW()
        ev = m.submodules.ev = EvaluatorEHW(distance_rule=self.distance_rule)

        # -- the controller board: straight through ---------------------------------------------
        wiring.connect(m, wiring.flipped(self.ctl_row), ctl.row)
        m.d.comb += [
            ctl.commit.eq(self.ctl_commit),
            ctl.x.eq(self.ctl_x),
            ctl.reflex_en.eq(self.ctl_reflex_en),
            self.ctl_motion.eq(ctl.motion),
        ]

        # -- the evaluator's model side: straight through (the host writes only while idle) -------
        wiring.connect(m, wiring.flipped(self.ev_model), ev.model)
        wiring.connect(m, wiring.flipped(self.ev_rate), ev.rate)
        m.d.comb += [
            ev.state_value.eq(self.ev_state_value),
            ev.state_we.eq(self.ev_state_we),
            ev.clear.eq(self.ev_clear),
            ev.reflex_en.eq(self.ev_reflex_en),
            self.ev_ready.eq(ev.ready),
            self.ev_n_states.eq(ev.n_states),
        ]

        # -- population and results RAMs ---------------------------------------------------------
        pop = m.submodules.pop = Memory(shape=GENOME_BITS, depth=self.p_max, init=[])
        res = m.submodules.res = Memory(shape=RESULT_LAYOUT, depth=self.p_max, init=[])
        pop_wr = pop.write_port()
        pop_rd = pop.read_port()  # the genome being loaded into the evaluator's shadow
        res_wr = res.write_port()
        res_rd = res.read_port()

        # -- the streamer ------------------------------------------------------------------------
        size = Signal.like(self.pop_size)
        load_idx = Signal(range(self.p_max + 1))  # controller whose rows are being written
        row = Signal(range(N_ROWS))
        eval_idx = Signal(range(self.p_max + 1))  # controller whose result comes next
        loading = Signal()  # in Stream: rows of load_idx are still to be written/started
        last_row = row == N_ROWS - 1
        start = Signal()  # the evaluator takes controller load_idx at this edge
        m.d.comb += start.eq(loading & last_row & ev.ready)
        idle = Signal()
        # Row ``row`` of the genome on pop_rd.data: a 50-way mux (Array), the same function as
        # word_select(row, ROW_BITS), which Yosys writes as a 950-bit shift (a 30-word shift, twice
        # a cycle, in Verilator: docs/hdl_in_the_loop.md).
        row_word = Signal(ROW_BITS)
        m.d.comb += row_word.eq(Array(pop_rd.data[r * ROW_BITS:(r + 1) * ROW_BITS] for r in range(N_ROWS))[row])

        m.d.comb += [
            pop_wr.addr.eq(self.pop_addr),
            pop_wr.data.eq(self.pop_data),
            pop_wr.en.eq(self.pop_we & idle),
            # The read address runs one controller ahead at a start, so that the next genome is
            # on pop_rd.data when its row 0 is written in the following cycle.
            pop_rd.addr.eq(load_idx + start),
            ev.row.addr.eq(row),
            ev.row.data.eq(row_word),
            ev.row.we.eq(loading),
            ev.start.eq(start),
            res_rd.addr.eq(self.res_addr),
            self.res_data.eq(res_rd.data),
            res_wr.addr.eq(eval_idx),
            res_wr.data.crashes.eq(ev.crashes),
            res_wr.data.loops.eq(ev.loops),
            res_wr.data.distance.eq(ev.distance),
            res_wr.data.fails.eq(ev.fails),
            res_wr.en.eq(ev.done & ~idle),
        ]

        m.d.sync += self.pop_done.eq(0)
        with m.FSM(init="Idle"):
            with m.State("Idle"):
                m.d.comb += idle.eq(1)
                # pop_rd.addr = load_idx = 0 here, so genome 0 is ready in the first Stream cycle.
                with m.If(self.go & (self.pop_size != 0)):
                    m.d.sync += [
                        size.eq(self.pop_size),
                        load_idx.eq(0),
                        eval_idx.eq(0),
                        row.eq(0),
                        loading.eq(1),
                        self.pop_cycles.eq(1),
                    ]
                    m.next = "Stream"

            with m.State("Stream"):
                m.d.comb += self.pop_busy.eq(1)
                m.d.sync += self.pop_cycles.eq(self.pop_cycles + 1)
                with m.If(loading):
                    with m.If(start):
                        m.d.sync += [load_idx.eq(load_idx + 1), row.eq(0)]
                        with m.If(load_idx + 1 == size):
                            m.d.sync += loading.eq(0)
                    with m.Elif(~last_row):
                        m.d.sync += row.eq(row + 1)
                    # else: the last row is rewritten until the evaluator is ready (harmless).
                with m.If(ev.done):
                    m.d.sync += eval_idx.eq(eval_idx + 1)
                    with m.If(eval_idx + 1 == size):
                        m.d.sync += [self.pop_done.eq(1), load_idx.eq(0)]
                        m.next = "Idle"
        return m


# -- host side: the board protocol, for any simulator ------------------------------------------------

SYSTEM_INPUTS = (
    "ctl_row__addr", "ctl_row__data", "ctl_row__we", "ctl_commit", "ctl_x", "ctl_reflex_en",
    "ev_model__state", "ev_model__motion", "ev_model__next", "ev_model__crash", "ev_model__valid",
    "ev_model__we", "ev_rate__state", "ev_rate__motion", "ev_rate__code", "ev_rate__we", "ev_state_value", "ev_state_we", "ev_clear", "ev_reflex_en",
    "pop_addr", "pop_data", "pop_we", "pop_size", "go", "res_addr",
)


def genome_words(population) -> list[int]:
    """Each genome of ``population`` (P, 50) as its 950-bit integer (a ``pop_data`` word: bit b
    is genome bit b, SPEC section 3)."""
    words = []
    for genome in population:
        value = 0
        for word in reversed(genome.tolist()):
            value = (value << ROW_BITS) | word
        words.append(value)
    return words


class SystemHost:
    """The host's side of ``SystemTop``: the board operations as coroutines over ``pins``.

    ``pins`` adapts one simulator: ``set(name, value)``, ``get(name) -> int`` and ``await
    tick()`` (inputs set before ``tick`` are sampled by the next rising edge; after it returns the
    registered outputs show that edge's result). The Amaranth backend and the cocotb backend use
    this same class, so both spend the same clock cycles on the same calls.

    Cycle counters (clock edges): ``controller_cycles`` (50 per download, 1 per motion),
    ``evaluator_cycles`` (``pop_cycles`` of every stream: the evaluator board's own work, row
    loading included), ``transfer_cycles`` (model writes, 2 per observation; rate writes, 1 per
    code; population writes and result reads, 1 per controller each: the host link).
    """

    def __init__(self, pins, p_max: int = P_MAX):
        from ga.world_model import WorldModel

        self.pins = pins
        self.p_max = p_max
        self.model = WorldModel()  # the host's copy: the update rule needs the current entry
        self.controller_cycles = 0
        self.evaluator_cycles = 0
        self.transfer_cycles = 0
        self.boot_cycles = 0
        self.streams = 0

    async def boot(self) -> None:
        """All inputs 0, then wait until the evaluator has swept its RAM (2049 cycles)."""
        pins = self.pins
        for name in SYSTEM_INPUTS:
            pins.set(name, 0)
        while True:
            await pins.tick()
            self.boot_cycles += 1
            if pins.get("ev_ready"):
                return

    def set_reflex(self, enabled: bool) -> None:
        """The reflex enable of both boards (a level: takes effect at the next edge)."""
        self.pins.set("ctl_reflex_en", int(enabled))
        self.pins.set("ev_reflex_en", int(enabled))

    async def reflex(self, enabled: bool) -> None:
        """``set_reflex`` as a job (no clock edge): a simulator's inputs are set from its own
        thread only (cocotb: a write from the bridge thread outside ``resume`` can be lost)."""
        self.set_reflex(enabled)

    async def load(self, rows) -> None:
        """Download one controller: 50 row writes, the commit with the last (50 cycles)."""
        self.controller_cycles += await write_rows(self.pins, "ctl_row", rows, strobe="ctl_commit")

    async def motion(self, state: int) -> int:
        """Present the sensor bits for one cycle and read the registered motion (1 cycle)."""
        self.pins.set("ctl_x", int(state))
        await self.pins.tick()
        self.controller_cycles += 1
        return self.pins.get("ctl_motion")

    async def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        """Apply the update rule of SPEC section 7 to the host's copy and write the resulting
        entry with the from-state, then the next state (2 cycles)."""
        pins = self.pins
        if not pins.get("ev_ready"):
            raise RuntimeError("the evaluator board is busy: a world-model write would be ignored")
        self.model.observe(int(state), int(motion), int(next_state), bool(crashed))
        pins.set("ev_model__state", int(state))
        pins.set("ev_model__motion", int(motion))
        pins.set("ev_model__next", int(self.model.next_state[state, motion]))
        pins.set("ev_model__crash", int(self.model.crash[state, motion]))
        pins.set("ev_model__valid", 1)
        pins.set("ev_model__we", 1)
        pins.set("ev_state_value", int(state))
        pins.set("ev_state_we", 1)
        await pins.tick()
        pins.set("ev_model__we", 0)
        pins.set("ev_state_value", int(next_state))
        await pins.tick()
        pins.set("ev_state_we", 0)
        self.transfer_cycles += 2

    async def write_rates(self, changes) -> None:
        """Failure-rate codes (``ga.fail_rates``): one (state, motion, code) per cycle."""
        pins = self.pins
        if not pins.get("ev_ready"):
            raise RuntimeError("the evaluator board is busy: a rate write would be ignored")
        for state, motion, code in changes:
            pins.set("ev_rate__state", int(state))
            pins.set("ev_rate__motion", int(motion))
            pins.set("ev_rate__code", int(code))
            pins.set("ev_rate__we", 1)
            await pins.tick()
            self.transfer_cycles += 1
        pins.set("ev_rate__we", 0)

    async def clear(self) -> None:
        """Empty the evaluator's model (S and every RAM entry: 2049 cycles; every rate code back to
        ``PRIOR_CODE``) and the host's copy."""
        from ga.world_model import WorldModel

        pins = self.pins
        pins.set("ev_clear", 1)
        await pins.tick()
        pins.set("ev_clear", 0)
        edges = 1
        while not pins.get("ev_ready"):
            await pins.tick()
            edges += 1
        self.transfer_cycles += edges
        self.model = WorldModel()

    async def write_model(self, model) -> None:
        """Copy a whole ``ga.world_model.WorldModel`` into an empty board: every valid entry and
        every state of S, one of each per cycle."""
        pins = self.pins
        entries, states = model.entries(), model.states
        for i in range(max(len(entries), len(states))):
            if i < len(entries):
                state, motion, next_state, crash = (int(v) for v in entries[i])
                pins.set("ev_model__state", state)
                pins.set("ev_model__motion", motion)
                pins.set("ev_model__next", next_state)
                pins.set("ev_model__crash", crash)
                pins.set("ev_model__valid", 1)
            pins.set("ev_model__we", int(i < len(entries)))
            if i < len(states):
                pins.set("ev_state_value", int(states[i]))
            pins.set("ev_state_we", int(i < len(states)))
            await pins.tick()
            self.transfer_cycles += 1
        pins.set("ev_model__we", 0)
        pins.set("ev_state_we", 0)
        self.model = model.copy()

    async def start_stream(self, words) -> None:
        """Write genome words (at most ``p_max``) into the population RAM, then hold ``go`` for one
        edge: the stream has started when this returns (``go`` is still set: clear it)."""
        pins = self.pins
        for i, word in enumerate(words):
            pins.set("pop_addr", i)
            pins.set("pop_data", word)
            pins.set("pop_we", 1)
            await pins.tick()
        pins.set("pop_we", 0)
        pins.set("pop_size", len(words))
        pins.set("go", 1)
        await pins.tick()

    async def evaluate(self, population) -> tuple[list[tuple[int, int, int, int]], int]:
        """(crashes, loops, distance, fails) of each controller of ``population`` (P, 50), and the
        evaluator cycles spent: streams of at most ``p_max`` controllers."""
        pins = self.pins
        words = genome_words(population)
        counts, cycles = [], 0
        for first in range(0, len(words), self.p_max):
            chunk = words[first:first + self.p_max]
            await self.start_stream(chunk)
            pins.set("go", 0)
            await pins.wait("pop_done")
            cycles += pins.get("pop_cycles")
            for i in range(len(chunk)):
                pins.set("res_addr", i)
                await pins.tick()
                counts.append(unpack_result(pins.get("res_data")))
            self.transfer_cycles += 2 * len(chunk)
            self.streams += 1
        self.evaluator_cycles += cycles
        return counts, cycles
