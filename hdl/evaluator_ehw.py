"""The evaluator board (SPEC section 8): world-model RAM, state set, AND-OR array, trace engine.

It computes (crashes, loops, distance) of the model-based fitness of SPEC section 7 for one
controller, bit-exact with ``ga.evaluator``, at one trace step (one tested state) per clock, and
``fails``, the failure-rate count F of ``ga.fail_rates`` (the summed rate codes of the
controller's motions in the obstacle states of S), in the same step.

Datapath
--------
- ``ram``: 2^(8+3) = 2048 entries of 9 bits (``hdl.ports.ModelEntry``, one 2048 x 9 block RAM),
  address ``state * 8 + motion`` (``Cat(motion, state)``). One synchronous write port (the host,
  or the Clear sweep) and one synchronous read port (the trace engine).
- ``rate_ram``: 2048 failure-rate codes of 8 bits (``ga.fail_rates``), same address, written by
  the host's rate port (``hdl.ports.RateWriteSignature``) or the Clear sweep (``PRIOR_CODE``) and
  read beside ``ram``: the code of the pair whose entry is on ``rd.data`` arrives with it.
- ``in_set``: the state set S as a 256-bit register (the host adds states; ``n_states`` counts).
- ``tested``, ``trace``: 256-bit registers, the sets of the pseudo-code. ``tested`` is cleared at
  start, ``trace`` is reloaded with a one-hot at each new trace.
- ``pick``: a log-depth priority encoder giving the smallest state of ``in_set & ~tested``: the
  next trace start s0, so S is walked in ascending order (SPEC pseudo-code) with no idle cycle
  spent skipping tested states.
- ``shadow`` / ``arch``: the controller's configuration, double-buffered like the controller
  board's: the row-write port fills ``shadow`` at any time (also while busy), ``start`` copies it
  (with a row written in the same cycle) into ``arch``, which drives the AND-OR array. Loading the
  next controller therefore overlaps evaluating this one. (``double_buffer=False`` drops the
  shadow: rows go straight into ``arch``, only while idle.)

One trace step per clock: the RAM's read address is combinational from its own registered
output. In each ``Trace`` cycle the entry e of the state ``cur`` issued in the previous cycle is
on ``rd.data``; the cycle decides (unknown / crash / free-space self-loop / loop / tested) whether
to follow ``e.next`` or to start a new trace at ``pick``, runs the chosen state x through the
reflex and the array to get its motion a, and presents address (x, a): x is tested in this cycle
and its entry arrives in the next one. Critical path: RAM data -> trace/tested bit-select ->
mux -> AND-OR array -> reflex -> RAM address.

FSM
---
``Idle`` -> (start) ``Begin`` -> ``Trace`` (N cycles) -> ``Idle``; ``Idle`` -> (clear) ``Clear``
(2048 cycles) -> ``Idle``. Reset enters ``Boot`` -> ``Clear``: the RAM is not a register (a
reset does not touch its contents), so a reset board sweeps it and is ready 2049 cycles after
reset with an empty model (S empty, every entry unknown). Wait for ``ready`` after reset.

- ``Idle``: ``ready`` = 1. Accepts world-model writes, rate writes, state additions, ``clear`` and ``start``
  (priority: clear, then start; a write in the same cycle as start is applied before the
  evaluation: the RAM write lands at that edge, the first read is one cycle later).
- ``Begin``: issues the first state (smallest of S); with S empty goes straight back to ``Idle``.
- ``Trace``: counts the entry on ``rd.data`` and issues the next state; when every state of S is
  tested, latches the results, pulses ``done`` and returns to ``Idle``.
- ``Clear``: writes 0 (unknown) to every RAM entry and ``PRIOR_CODE`` to every rate code; S was
  emptied on entering.

Cycle cost
----------
Evaluation: ``cycles`` = N + 1 for a model of N >= 0 states (``Begin`` + one ``Trace`` cycle per
state of S); ``done`` pulses and ``busy`` falls N + 1 edges after the edge that samples ``start``.
Loading 50 rows costs 50 cycles, the last of which may carry ``start``; when the rows of the next
controller are written while this one is evaluated (overlap), a population of P controllers costs
about P * max(N + 2, 51) cycles. Either way <= 2N + 60 per controller.

Handshake
---------
``start`` is honoured only when ``ready`` (state ``Idle``); a start while busy is ignored, and so
are world-model writes, rate writes, state additions and ``clear`` while busy (``ready`` low). Row writes are
always accepted (they only touch the shadow). Results (``crashes``, ``loops``, ``distance``,
``fails``, ``cycles``) are result registers: they change only at the edge that ends an evaluation (the
same edge that raises ``done`` for one cycle and lowers ``busy``) and hold until the next one
ends, so the host may read them during the next evaluation. ``reflex_en`` is sampled at start.
"""

from __future__ import annotations

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out
from amaranth.utils import exact_log2

from ga.fail_rates import FAIL_BITS, PRIOR_CODE, RATE_BITS
from ga.genome import N_ROWS, ROW_BITS
from ga.motions import (DEFAULT_DISTANCE_RULE, MAX_MOTION_DISTANCE_MM, N_INPUTS, N_MOTIONS, N_OUTPUTS,
                        N_STATES, OBSTACLE_MASK, REFLEX_MOTION, SECTOR_SHIFT, motion_distances)
from hdl.and_or_array import AndOrArray, _check_positive
from hdl.ports import COUNT_BITS, DISTANCE_BITS, ModelEntry, ModelWriteSignature, RateWriteSignature, RowWriteSignature

RAM_DEPTH = N_STATES * N_MOTIONS  # 2^(n+3)
CYCLE_BITS = 16
assert N_STATES * MAX_MOTION_DISTANCE_MM < 1 << DISTANCE_BITS
assert ModelEntry.UNKNOWN == 0  # the Clear sweep writes the all-zero word


WORD = 32  # the word of the state-set helpers below: one machine word in a simulator


def _bit_of(m, bits, index, name: str):
    """``bits[index]`` for a variable ``index`` (``len(bits)`` = 2^len(index), a multiple of
    ``WORD``), as a Signal ``name``: a balanced mux tree picks the 32-bit word, a 32-bit shift the
    bit. The same function as ``bits.bit_select(index, 1)``, which Yosys writes as one
    ``len(bits)``-bit shift (a multi-word shift in Verilator: docs/hdl_in_the_loop.md)."""
    level = [bits[i:i + WORD] for i in range(0, len(bits), WORD)]
    for b in range(exact_log2(WORD), len(index)):
        level = [Mux(index[b], level[i + 1], level[i]) for i in range(0, len(level), 2)]
    bit = Signal(name=name)
    m.d.comb += bit.eq(level[0].bit_select(index[:exact_log2(WORD)], 1))
    return bit


def _one_hot(m, index, width: int, name: str):
    """The ``width``-bit one-hot of a variable ``index`` (width = 2^len(index)), as a Signal
    ``name``: a 32-bit one-hot of the low bits placed in the word the high bits select. The same
    function as ``Const(1, width) << index``, which Yosys writes as a (2 width - 1)-bit shift."""
    low_bits = exact_log2(WORD)
    low = Signal(WORD, name=f"{name}_low")
    m.d.comb += low.eq(Const(1, 1) << index[:low_bits])
    hot = Signal(width, name=name)
    m.d.comb += hot.eq(Cat(Mux(index[low_bits:] == w, low, 0) for w in range(width // WORD)))
    return hot


def _lowest_set(bits, lo: int, hi: int):
    """(any, index - lo) of the lowest set bit of ``bits[lo:hi]`` (hi - lo a power of 2): a
    balanced tree of 2:1 muxes, log2(hi - lo) levels deep."""
    if hi - lo == 1:
        return bits[lo], Const(0, 0)
    mid = (lo + hi) // 2
    any_lo, idx_lo = _lowest_set(bits, lo, mid)
    any_hi, idx_hi = _lowest_set(bits, mid, hi)
    return any_lo | any_hi, Cat(Mux(any_lo, idx_lo, idx_hi), ~any_lo)


class EvaluatorEHW(wiring.Component):
    """The evaluator EHW board: model-based fitness counts of one controller per run.

    Parameters
    ----------
    k : int
        Rows of the AND-OR array (default 50). n = 8 and m = 3 are fixed by SPEC section 4.
    double_buffer : bool
        True (default): a shadow configuration, so the next controller's rows load while this
        one is evaluated. False: the rows go straight into the active configuration and are
        accepted only when ``ready`` (saves k x 19 = 950 flip-flops, e.g. for a small FPGA;
        loading then costs 50 cycles more per controller).
    lookahead : bool
        False (default): one AND-OR array, on the state issued this cycle (the entry's next state
        or the next untested state, whichever the entry decides). True: two arrays, one on each
        candidate, and the decision picks the motion: the same counts, cycle for cycle, with the
        RAM's read data no longer in series with the array (the learner's lanes; about 450 LUT4
        more).

    Ports
    -----
    row : In(RowWriteSignature(k))
        Row-write port into the shadow configuration (``hdl.ports``, as the controller board's);
        addresses >= k are ignored. Accepted in every state (``double_buffer=False``: only when
        ready). Verilog: ``row__addr``, ``row__data``, ``row__we``.
    model : In(ModelWriteSignature())
        World-model write port (``hdl.ports``): entry (``model.state``, ``model.motion``) :=
        {``next``, ``crash``, ``valid``} at the next edge when ``model.we`` and ``ready``. The
        host applies the update rule (``ga.world_model``) and writes the resulting entry.
        Verilog: ``model__state``, ``model__motion``, ``model__next``, ``model__crash``,
        ``model__valid``, ``model__we``.
    rate : In(RateWriteSignature())
        Failure-rate write port (``hdl.ports``): code (``rate.state``, ``rate.motion``) :=
        ``rate.code`` at the next edge when ``rate.we`` and ``ready``. Verilog: ``rate__state``,
        ``rate__motion``, ``rate__code``, ``rate__we``.
    state_value : In(8), state_we : In(1)
        Add ``state_value`` to S at the next edge, when ``ready`` (adding a member is harmless).
    clear : In(1)
        When ``ready``: empty S and sweep every RAM entry to unknown (2048 cycles, busy).
    reflex_en : In(1)
        Put the reflex in front of the array (SPEC section 6); sampled at start.
    start : In(1)
        When ``ready``: copy the shadow into the active configuration and evaluate.
    ready : Out(1)
        Idle: start, clear and model/state writes are accepted.
    busy : Out(1)
        Evaluating or clearing (= not ready).
    done : Out(1)
        One-cycle pulse: the result registers have just been updated.
    crashes, loops : Out(9); distance : Out(16); fails : Out(16); cycles : Out(16)
        Results of the last finished evaluation (``cycles`` = N + 1).
    n_states : Out(9)
        |S|.
    """

    def __init__(self, k: int = N_ROWS, double_buffer: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE,
                 lookahead: bool = False):
        self.k = _check_positive("k", k)
        self.distance_rule = distance_rule
        self.distances = motion_distances(distance_rule)  # dist[a]; refuses an unknown rule
        if not isinstance(double_buffer, bool):
            raise TypeError(f"double_buffer must be a bool, got {double_buffer!r}")
        self.double_buffer = double_buffer
        if not isinstance(lookahead, bool):
            raise TypeError(f"lookahead must be a bool, got {lookahead!r}")
        self.lookahead = lookahead
        self.row_bits = ROW_BITS
        super().__init__({
            "row": In(RowWriteSignature(self.k)),
            "model": In(ModelWriteSignature()),
            "rate": In(RateWriteSignature()),
            "state_value": In(N_INPUTS),
            "state_we": In(1),
            "clear": In(1),
            "reflex_en": In(1),
            "start": In(1),
            "ready": Out(1),
            "busy": Out(1),
            "done": Out(1),
            "crashes": Out(COUNT_BITS),
            "loops": Out(COUNT_BITS),
            "distance": Out(DISTANCE_BITS),
            "fails": Out(FAIL_BITS),
            "cycles": Out(CYCLE_BITS),
            "n_states": Out(COUNT_BITS),
        })

    def elaborate(self, platform):
        m = Module()
        k, W = self.k, self.row_bits
        array = m.submodules.array = AndOrArray(n=N_INPUTS, m=N_OUTPUTS, k=k)
        ram = m.submodules.ram = Memory(shape=ModelEntry, depth=RAM_DEPTH, init=[])
        wr = ram.write_port()
        rd = ram.read_port()  # synchronous: rd.data is the entry at last cycle's rd.addr
        rate_ram = m.submodules.rate_ram = Memory(shape=RATE_BITS, depth=RAM_DEPTH, init=[])
        rate_wr = rate_ram.write_port()
        rate_rd = rate_ram.read_port()  # the code of rd.data's pair, in the same cycle

        # -- configuration: shadow filled by the row port, copied to arch at start ----------------
        if self.double_buffer:
            shadow = Signal(k * W)
            arch = Signal(k * W)
            row_write = self.row.we  # always: the shadow never drives the array
        else:
            shadow = arch = Signal(k * W)  # the rows go straight to the array: only while idle
            row_write = self.row.we & self.ready
        shadow_next = Signal(k * W)  # the shadow after this cycle's row write: what start takes
        m.d.comb += shadow_next.eq(shadow)
        for r in range(k):
            with m.If(row_write & (self.row.addr == r)):
                m.d.comb += shadow_next[r * W:(r + 1) * W].eq(self.row.data)
        m.d.sync += shadow.eq(shadow_next)

        # -- state set S ---------------------------------------------------------------------------
        in_set = Signal(N_STATES)
        tested = Signal(N_STATES)
        trace = Signal(N_STATES)
        add_state = self.state_we & self.ready
        value_in_set = _bit_of(m, in_set, self.state_value, "value_in_set")
        value_hot = _one_hot(m, self.state_value, N_STATES, "value_hot")
        with m.If(add_state & ~value_in_set):
            m.d.sync += [
                in_set.eq(in_set | value_hot),
                self.n_states.eq(self.n_states + 1),
            ]

        # -- trace engine (combinational part) -------------------------------------------------------
        cur = Signal(N_INPUTS)  # the state whose entry is on rd.data (issued last cycle)
        cur_motion = Signal(N_OUTPUTS)

        reflex_r = Signal()
        tracing = Signal()  # in Trace: rd.data is a live entry
        entry = rd.data
        s2 = entry.next
        free_self = (s2 == cur) & ((cur & OBSTACLE_MASK) == 0)
        moves = tracing & entry.moves  # the pseudo-code gets past (i) and (ii)
        crashed = tracing & entry.crashed()  # (ii)
        goes_on = moves & ~free_self
        in_trace = _bit_of(m, trace, s2, "in_trace")
        in_tested = _bit_of(m, tested, s2, "in_tested")
        loop_hit = goes_on & in_trace  # (iv)
        follow = goes_on & ~in_tested  # trace (and so tested) does not hold s2: continue there

        untested = Signal(N_STATES)
        m.d.comb += untested.eq(in_set & ~tested)
        pick_any, pick_state = _lowest_set(untested, 0, N_STATES)

        x = Signal(N_INPUTS)  # the state issued this cycle
        motion = Signal(N_OUTPUTS)
        issue = Signal()
        m.d.comb += [
            x.eq(Mux(follow, s2, pick_state)),
            issue.eq(follow | pick_any),
        ]
        reflex_table = Array(Const(int(a), N_OUTPUTS) for a in REFLEX_MOTION)

        def motion_of(state, arr):
            """The motion in ``state``: the reflex's (outside obstacles, when on) or ``arr``'s."""
            m.d.comb += [arr.arch.eq(arch), arr.x.eq(state)]
            use_reflex = reflex_r & ((state & OBSTACLE_MASK) == 0)
            return Mux(use_reflex, reflex_table[state[SECTOR_SHIFT:]], arr.y)

        if self.lookahead:  # both candidates' motions, then the entry's decision picks one
            ahead = m.submodules.array_next = AndOrArray(n=N_INPUTS, m=N_OUTPUTS, k=k)
            m.d.comb += motion.eq(Mux(follow, motion_of(s2, ahead), motion_of(pick_state, array)))
        else:
            m.d.comb += motion.eq(motion_of(x, array))
        m.d.comb += [rd.addr.eq(Cat(motion, x)), rate_rd.addr.eq(rd.addr)]
        step_fails = Mux(tracing & ((cur & OBSTACLE_MASK) != 0), rate_rd.data, 0)  # obstacle states only
        step_distance = Array(Const(int(d), DISTANCE_BITS) for d in self.distances)[cur_motion]

        # -- accumulators (results are latched at the end) -------------------------------------------
        acc_crashes = Signal(COUNT_BITS)
        acc_loops = Signal(COUNT_BITS)
        acc_distance = Signal(DISTANCE_BITS)
        acc_fails = Signal(FAIL_BITS)
        acc_cycles = Signal(CYCLE_BITS)
        clear_addr = Signal(range(RAM_DEPTH))

        # RAM writes: the host's while idle, the Clear sweep's while clearing.
        host_write = self.model.we & self.ready
        m.d.comb += [
            wr.addr.eq(Cat(self.model.motion, self.model.state)),
            *wr.data.store(self.model.next, self.model.crash, self.model.valid),
            wr.en.eq(host_write),
            rate_wr.addr.eq(Cat(self.rate.motion, self.rate.state)),
            rate_wr.data.eq(self.rate.code),
            rate_wr.en.eq(self.rate.we & self.ready),
        ]

        onehot = _one_hot(m, x, N_STATES, "x_hot")

        def issue_state(new_trace):
            """Test x: mark it, remember it for the next cycle (its entry is read meanwhile)."""
            m.d.sync += [
                tested.eq(tested | onehot),
                trace.eq(Mux(new_trace, onehot, trace | onehot)),
                cur.eq(x),
                cur_motion.eq(motion),
            ]

        def finish():
            m.d.sync += [
                self.crashes.eq(acc_crashes + crashed),
                self.loops.eq(acc_loops + loop_hit),
                self.distance.eq(acc_distance + Mux(moves, step_distance, 0)),
                self.fails.eq(acc_fails + step_fails),
                self.cycles.eq(acc_cycles + 1),
                self.done.eq(1),
            ]

        m.d.sync += self.done.eq(0)
        with m.FSM(init="Boot"):
            with m.State("Boot"):
                # After reset: sweep the RAM, so that a reset board holds an empty model. (A state
                # of its own, so that fsm_state changes after reset: Icarus never evaluates the
                # generated `always @*` blocks of a register that keeps its initial value.)
                m.d.comb += self.busy.eq(1)
                m.d.sync += clear_addr.eq(0)
                m.next = "Clear"

            with m.State("Idle"):
                m.d.comb += self.ready.eq(1)
                with m.If(self.clear):
                    m.d.sync += [in_set.eq(0), self.n_states.eq(0), clear_addr.eq(0)]
                    m.next = "Clear"
                with m.Elif(self.start):
                    if self.double_buffer:
                        m.d.sync += arch.eq(shadow_next)
                    m.d.sync += [
                        reflex_r.eq(self.reflex_en),
                        tested.eq(0),
                        acc_crashes.eq(0),
                        acc_loops.eq(0),
                        acc_distance.eq(0),
                        acc_fails.eq(0),
                        acc_cycles.eq(0),
                    ]
                    m.next = "Begin"

            with m.State("Begin"):
                # tracing = 0: no entry to count; x = pick_state (the smallest state of S).
                m.d.comb += self.busy.eq(1)
                m.d.sync += acc_cycles.eq(1)
                with m.If(issue):
                    issue_state(new_trace=1)
                    m.next = "Trace"
                with m.Else():  # S is empty
                    finish()
                    m.next = "Idle"

            with m.State("Trace"):
                m.d.comb += [self.busy.eq(1), tracing.eq(1)]
                m.d.sync += [
                    acc_crashes.eq(acc_crashes + crashed),
                    acc_loops.eq(acc_loops + loop_hit),
                    acc_distance.eq(acc_distance + Mux(moves, step_distance, 0)),
                    acc_fails.eq(acc_fails + step_fails),
                    acc_cycles.eq(acc_cycles + 1),
                ]
                with m.If(issue):
                    issue_state(new_trace=~follow)
                with m.Else():  # every state of S is tested
                    finish()
                    m.next = "Idle"

            with m.State("Clear"):
                m.d.comb += [
                    self.busy.eq(1),
                    wr.addr.eq(clear_addr),
                    wr.data.eq(0),  # every bit 0: ModelEntry.UNKNOWN, not moving
                    wr.en.eq(1),
                    rate_wr.addr.eq(clear_addr),
                    rate_wr.data.eq(PRIOR_CODE),  # a pair never executed
                    rate_wr.en.eq(1),
                ]
                m.d.sync += clear_addr.eq(clear_addr + 1)
                with m.If(clear_addr == RAM_DEPTH - 1):
                    m.next = "Idle"
        return m
