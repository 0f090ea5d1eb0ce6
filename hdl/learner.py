"""The learning engine of SPEC section 12: the hardware GA and L evaluator lanes on one chip.

Bit-exact with ``ga.hardware_ga`` (the algorithm, the random source, the draw schedule and the
integer score are defined there; this module only says how the hardware does it).

Datapath
--------
- ``bank[r]`` (r = 0..49): row r of every individual of both population buffers, one
  ``Memory(shape=19, depth=2 * 2^ceil(log2 P))`` each, address ``Cat(index, buffer)``. One
  synchronous read port and one write port per bank: in a pass the lanes read the parents from
  the current buffer and write the children into the other one.
- ``lane[j]`` (:class:`Lane`): an ``EvaluatorEHW`` (its own copy of the world-model RAM, state
  set and trace engine: every model write goes to every lane, so the copies stay identical), the
  lane's seven xorshift32 generators, a replica of the score RAM (both buffers: the previous
  pass's scores for its tournaments, this pass's being written), the tournament comparator and
  the row mutation datapath.
- ``group[k]`` (k = 0..M-1, M = :func:`bank_groups` = L lanes): the banks of rows k, k + M, ...
  Lane j draws row r - j when lane 0 draws row r, so the lanes ask M consecutive rows at most
  in a cycle, each in its own group: a group serves one lane a cycle through one register of the
  request (address, bank), one of the write and one read multiplexer of its banks; a lane's row
  comes from the group of its row through an M:1 multiplexer into a register, and the host reads
  through the same multiplexers. So each bank's read data goes to one multiplexer (not to every
  lane and to a host gather of the 50 banks), and every path between a lane and a bank starts
  or ends at a register: ``ga.hardware_ga.ROW_LATENCY`` = 3 cycles from a row's draw to its
  shadow write.
- A global slot counter (``tau`` in 0..C-1, ``slot`` in 0..S) whose value reaches lane j through
  j registers: lane j runs j cycles behind lane 0. A lane asks bank r in the cycle it draws its
  row r, so two lanes never ask the same group in one cycle (their rows differ by their lane
  distance, less than M); the same holds for the bank writes, for the score writes and for the
  running best (one lane finishes per cycle, in the children's order).
- The result bus (the finishing lane's index and counts) is registered before the score, the
  running best and the score replicas (``ga.hardware_ga.RESULT_LATENCY`` = 1 cycle of drain).

Timing of a slot (lane time tau; C = max(N + 2, 2T + 54), ``ga.hardware_ga.slot_cycles``)
---------------------------------------------------------------------------------------
- tau = 0 .. 2T: one ``SEL`` draw a cycle; draws 0 .. 2T-1 are contestants (score replica read,
  compared one cycle later: first of tournament a, then of b), draw 2T the crossover decision.
- tau = 2T+1 .. 2T+50: row r = tau - 2T - 1 (stage 1): the six row generators draw, the parent
  (a or b) is chosen, the mutation command is computed from the draws, and the request goes to
  the group of bank r; stage 2: the group's register drives bank r's address; stage 3: the
  bank's data goes through the group's and the lane's multiplexers into the lane's row register;
  stage 4 (tau = r + 2T + 4): the lane mutates the row and writes it into its evaluator's shadow
  configuration, and the group's write register latches it, which lands in bank r of the next
  buffer in stage 5.
- tau = C - 1: start the evaluator on the child (its rows all in the shadow). It runs N + 1
  cycles, during the next slot, while the next child is bred; its counts are scored and written
  to every score replica (the next buffer) and into the running best one cycle after it finishes.

A pass is S = ceil(P / L) slots of breeding, one slot more for the last evaluations and
L + 1 cycles for the lanes behind and the result bus: ``(S + 1) C + L + 1`` cycles
(``ga.hardware_ga.pass_cycles``, checked against this RTL in tests/test_learner.py). Between
passes the buffers swap and the best of the pass becomes the next pass's elite.

Host protocol (all in ``Idle``, ``ready`` high)
------------------------------------------------
World model: the ``model`` port (``hdl.ports.ModelWriteSignature``), ``state_*`` and ``clear``
of ``EvaluatorEHW``, broadcast to every lane. Population: ``pop_index``, ``pop_row``, ``pop_data``, ``pop_we`` write a row of the
current buffer (and mark the population unevaluated: the next pass only evaluates it);
``pop_index``, ``pop_row`` read a row (``pop_rdata``, one cycle later). ``seed`` + ``seed_we``
seed every generator (``ga.hardware_ga.lane_seeds``). ``generations`` + ``start``: run that many
passes; ``done`` pulses at the end; ``best_*`` hold the best of the last pass (index in the current
buffer, score, counts) and ``cycles`` the busy cycles of the last run. With ``avoid_en`` (and
``avoid_state``, ``avoid_motion`` held during the run) ``escape_*`` hold the first child of
highest score whose array motion in ``avoid_state`` is not ``avoid_motion`` (``escape_found``:
there is one); each lane ORs the outputs of the rows firing in that state as they stream in.
"""

from __future__ import annotations

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ga import hardware_ga as hg
from ga.genome import N_ROWS, OUTPUT_SHIFT, ROW_BITS
from ga.motions import MAX_MOTION_DISTANCE_MM, N_INPUTS, N_OUTPUTS
from ga.operators import CONTRADICTION, DONT_CARE, NEGATIVE, POSITIVE
from hdl.evaluator_ehw import EvaluatorEHW
from hdl.ports import COUNT_BITS, DISTANCE_BITS, ModelWriteSignature, row_addr_bits

TAU_BITS = 10  # C <= max(258, 2T + 54) < 1024 for T <= 480
ROW_INDEX_BITS = row_addr_bits(N_ROWS)
# The evaluator's model-side inputs, broadcast from the learner to every lane's evaluator.
_MODEL_MEMBERS = ("state", "motion", "next", "crash", "valid", "we")  # of ModelWriteSignature
_STATE_PORTS = ("state_value", "state_we", "clear", "reflex_en")


def _broadcast(m, source, sink):
    """Drive ``sink``'s model port and state inputs from ``source``'s (one writer, many copies:
    ``wiring.connect`` joins one port to one)."""
    m.d.comb += [getattr(sink.model, name).eq(getattr(source.model, name)) for name in _MODEL_MEMBERS]
    m.d.comb += [getattr(sink, name).eq(getattr(source, name)) for name in _STATE_PORTS]


def _xorshift(x):
    """One xorshift32 step as a 32-bit expression (``ga.hardware_ga.xorshift32``)."""
    x = (x ^ (x << 13))[:32]
    x = (x ^ (x >> 17))[:32]
    return (x ^ (x << 5))[:32]


def bank_groups(config: hg.HardwareGAConfig) -> int:
    """The number M of bank groups: group k holds the banks of rows k, k + M, ... .

    Lane j draws row r - j when lane 0 draws row r (its slot counter runs j cycles behind), so in
    one slot the rows asked in a cycle are consecutive and M = L groups are enough for each group
    to serve one lane a cycle. Lanes in different slots could both be in their row phase only if
    a slot were shorter than 50 + L - 1 cycles (C >= 2T + 54: L > 2T + 5); then one group per
    row (M = 50: the lanes' rows differ by less than C)."""
    return config.lanes if config.lanes <= 2 * config.tournament + 5 else N_ROWS


def index_bits(population: int) -> int:
    return max(1, (population - 1).bit_length())


def _model_ports():
    """The evaluator's world-model side: the model write port and the state-set inputs."""
    return {"model": In(ModelWriteSignature()), "state_value": In(N_INPUTS), "state_we": In(1),
            "clear": In(1), "reflex_en": In(1)}


class Lane(wiring.Component):
    """One evaluator lane with its generators, tournament and row mutation (see the module
    docstring). ``index`` is the lane number j (its generators' salts).

    Ports: ``tau``, ``slot``, ``active`` (the slot counter as lane j sees it), ``c_last`` (C - 1),
    ``copy_mode``, ``cur_buf``, ``best_prev`` (pass constants), ``seed``/``seed_we``, the score
    replica's write port ``score_*``, the model port and state inputs (to the evaluator), the bank request
    ``rd_en``/``rd_row``/``rd_addr`` and the row ``data_row`` whose data is expected on
    ``rd_data`` this cycle, the bank write ``wr_*``, and the result ``result_valid``,
    ``result_index``, ``crashes``, ``loops``, ``distance``; ``n_states``, ``ready`` from the
    evaluator.
    """

    def __init__(self, config: hg.HardwareGAConfig, index: int, distance_rule: str = "covered"):
        self.config = config
        self.index = index
        self.distance_rule = distance_rule
        ib = index_bits(config.population)
        self.ib = ib
        ports = {
            "tau": In(TAU_BITS), "slot": In(range(config.slots + 1)), "active": In(1),
            "c_last": In(TAU_BITS), "copy_mode": In(1), "cur_buf": In(1), "best_prev": In(ib),
            "seed": In(32), "seed_we": In(1),
            "score_addr": In(ib + 1), "score_data": In(hg.SCORE_BITS), "score_we": In(1),
            "rd_en": Out(1), "rd_row": Out(ROW_INDEX_BITS), "rd_addr": Out(ib + 1),
            "data_en": Out(1), "data_row": Out(ROW_INDEX_BITS), "rd_data": In(ROW_BITS),
            "wr_en": Out(1), "wr_row": Out(ROW_INDEX_BITS), "wr_addr": Out(ib + 1),
            "wr_data": Out(ROW_BITS),
            "result_valid": Out(1), "result_index": Out(ib),
            "crashes": Out(COUNT_BITS), "loops": Out(COUNT_BITS), "distance": Out(DISTANCE_BITS),
            "n_states": Out(COUNT_BITS), "ready": Out(1),
            "avoid_en": In(1), "avoid_state": In(N_INPUTS), "avoid_motion": In(N_OUTPUTS),
            "result_eligible": Out(1),
        }
        ports.update(_model_ports())
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg, ib, T, P, L = self.config, self.ib, self.config.tournament, self.config.population, self.config.lanes
        ev = m.submodules.evaluator = EvaluatorEHW(double_buffer=True, distance_rule=self.distance_rule,
                                                   lookahead=True)
        _broadcast(m, self, ev)
        m.d.comb += [self.n_states.eq(ev.n_states), self.ready.eq(ev.ready)]

        scores = m.submodules.scores = Memory(shape=hg.SCORE_BITS, depth=2 << ib, init=[])
        score_wr = scores.write_port()
        score_rd = scores.read_port()
        m.d.comb += [score_wr.addr.eq(self.score_addr), score_wr.data.eq(self.score_data),
                     score_wr.en.eq(self.score_we)]

        # -- generators -----------------------------------------------------------------------
        gens = [Signal(32, name=f"gen{g}") for g in range(hg.GENERATORS)]
        draws = [Signal(32, name=f"draw{g}") for g in range(hg.GENERATORS)]
        for g in range(hg.GENERATORS):
            m.d.comb += draws[g].eq(_xorshift(gens[g]))
            salted = Signal(32, name=f"salted{g}")
            m.d.comb += salted.eq(self.seed ^ hg.seed_salt(self.index, g))
            with m.If(self.seed_we):
                m.d.sync += gens[g].eq(Mux(salted == 0, hg.SEED_FALLBACK, salted))

        tau, slot = self.tau, self.slot
        breeding_slot = self.active & (slot < cfg.slots)
        sel_step = breeding_slot & (tau < 2 * T + 1)
        row_start = 2 * T + 1
        row_step = breeding_slot & (tau >= row_start) & (tau < row_start + N_ROWS)
        with m.If(sel_step):
            m.d.sync += gens[hg.SEL].eq(draws[hg.SEL])
        with m.If(row_step):
            m.d.sync += [gens[g].eq(draws[g]) for g in hg.ROW_GENERATORS]

        child = Signal(range(cfg.slots * L + 1))
        m.d.comb += child.eq(slot * L + self.index)
        child_valid = child < P
        elite = ~self.copy_mode & (child == 0)
        plain = self.copy_mode | elite  # copied unchanged: no crossover, no mutation

        # -- selection: tournaments a (draws 0..T-1) and b (T..2T-1), crossover (draw 2T) ----------
        field = draws[hg.SEL][hg.FIELD16_SHIFT:]
        contestant = Signal(ib)
        m.d.comb += [
            contestant.eq((field * P)[16:]),
            score_rd.addr.eq(Cat(contestant, self.cur_buf)),  # the scores of the parents' buffer
        ]
        cont_r = Signal(ib)
        k_r = Signal(TAU_BITS)  # the draw whose score is on score_rd.data
        compare = Signal()
        m.d.sync += [cont_r.eq(contestant), k_r.eq(tau), compare.eq(sel_step & (tau < 2 * T))]
        par_a, par_b = Signal(ib), Signal(ib)
        best_a, best_b = Signal(hg.SCORE_BITS), Signal(hg.SCORE_BITS)
        cross = Signal()
        got = score_rd.data
        with m.If(compare):
            with m.If(k_r < T):
                with m.If((k_r == 0) | (got > best_a)):
                    m.d.sync += [par_a.eq(cont_r), best_a.eq(got)]
            with m.Else():
                with m.If((k_r == T) | (got > best_b)):
                    m.d.sync += [par_b.eq(cont_r), best_b.eq(got)]
        with m.If(sel_step & (tau == 2 * T)):
            m.d.sync += cross.eq(field < cfg.cross_threshold)

        # -- breeding, stage 1: draw, choose the parent, ask bank r; the mutation command -----------
        # (ROW_LATENCY = 3 cycles to the shadow: the banks' group registers latch the address
        # (stage 2), the bank reads (its data in stage 3), the group registers latch the data
        # (stage 4: mutated and written into the shadow; the bank write is latched by the group
        # registers and lands in stage 5).)
        row = Signal(ROW_INDEX_BITS)
        m.d.comb += row.eq(tau - row_start)
        r0, r1, r2, r3, r4, r5 = (draws[g] for g in hg.ROW_GENERATORS)
        take_b = cross & ~plain & r0[hg.TAKE_B_BIT]
        source = Mux(self.copy_mode, child, Mux(elite, self.best_prev, Mux(take_b, par_b, par_a)))
        m.d.comb += [
            self.rd_en.eq(row_step),
            self.rd_row.eq(row),
            self.rd_addr.eq(Cat(source[:ib], self.cur_buf)),
        ]
        # the mutation command (ga.hardware_ga._mutate_rows), from this row's draws
        fresh_fields = []
        for i in range(N_INPUTS):
            byte = (r4 if i < 4 else r5)[8 * (i % 4):8 * (i % 4) + 8]
            negative = r3[hg.FRESH_POLARITY_SHIFT + i]
            fresh_fields.append(Mux(byte < cfg.connect_threshold, Cat(~negative, negative), DONT_CARE))
        cmd = {
            "lit_event": ~plain & (r0[hg.FIELD16_SHIFT:] < cfg.literal_threshold),
            "lit_index": r0[hg.LITERAL_INDEX_SHIFT:hg.LITERAL_INDEX_SHIFT + 3],
            "polarity": r0[hg.POLARITY_BIT],
            "to_dc": r0[hg.TO_DC_SHIFT:hg.TO_DC_SHIFT + 8] < cfg.to_dc_threshold,
            "out_event": ~plain & (r1[hg.FIELD16_SHIFT:] < cfg.output_threshold),
            "out_bit": (r1[:8] * 3)[8:10],
            "sw_event": ~plain & (r2[hg.FIELD16_SHIFT:] < cfg.switch_threshold),
            "code": ((r2[:8] * 7)[8:11] + 1)[:N_OUTPUTS],
            "rep_event": ~plain & (r3[hg.FIELD16_SHIFT:] < cfg.replace_threshold),
            "fresh": Cat(*fresh_fields, ((r3[:8] * 7)[8:11] + 1)[:N_OUTPUTS]),
        }
        # the row's pipeline: stage k holds (valid, row, command) of the row drawn k - 1 cycles ago
        stages = [(row_step, row, cmd)]
        for k in (2, 3, 4):
            valid_k = Signal(name=f"s{k}_valid")
            row_k = Signal(ROW_INDEX_BITS, name=f"s{k}_row")
            cmd_k = {}
            for key, value in stages[-1][2].items():
                cmd_k[key] = Signal(len(value), name=f"s{k}_{key}")
                m.d.sync += cmd_k[key].eq(value)
            m.d.sync += [valid_k.eq(stages[-1][0]), row_k.eq(stages[-1][1])]
            stages.append((valid_k, row_k, cmd_k))
        m.d.comb += [self.data_en.eq(stages[2][0]), self.data_row.eq(stages[2][1])]
        stage4, row_r, c = stages[3]

        # -- breeding, stage 4: mutate the row (ga.hardware_ga._mutate_rows), write it -------------
        word = self.rd_data
        fields = []
        for i in range(N_INPUTS):
            old = word[2 * i:2 * i + 2]
            new = Signal(2, name=f"new_field{i}")
            with m.Switch(old):
                with m.Case(DONT_CARE):
                    m.d.comb += new.eq(Mux(c["polarity"], NEGATIVE, POSITIVE))
                with m.Case(CONTRADICTION):
                    m.d.comb += new.eq(DONT_CARE)
                with m.Case(POSITIVE):
                    m.d.comb += new.eq(Mux(c["to_dc"], DONT_CARE, NEGATIVE))
                with m.Case(NEGATIVE):
                    m.d.comb += new.eq(Mux(c["to_dc"], DONT_CARE, POSITIVE))
            fields.append(Mux(c["lit_event"] & (c["lit_index"] == i), new, old))
        outputs = Signal(N_OUTPUTS)
        m.d.comb += outputs.eq(word[OUTPUT_SHIFT:] ^ Cat(*[c["out_event"] & (c["out_bit"] == b)
                                                          for b in range(N_OUTPUTS)]))
        switched = Mux(outputs != 0, 0, c["code"])
        mutated = Signal(ROW_BITS)
        m.d.comb += mutated.eq(Mux(c["rep_event"], c["fresh"],
                                   Cat(*fields, Mux(c["sw_event"], switched, outputs))))
        m.d.comb += [
            ev.row.addr.eq(row_r), ev.row.data.eq(mutated), ev.row.we.eq(stage4),
            self.wr_en.eq(stage4 & child_valid), self.wr_row.eq(row_r),
            self.wr_addr.eq(Cat(child[:ib], ~self.cur_buf)), self.wr_data.eq(mutated),
        ]

        # -- the escape: the child's array motion in avoid_state, one row per cycle as it streams -----
        violated = Cat(*[Cat(~self.avoid_state[i], self.avoid_state[i]) for i in range(N_INPUTS)])
        fires = (mutated[:OUTPUT_SHIFT] & violated) == 0
        motion_acc = Signal(N_OUTPUTS)
        motion_next = Signal(N_OUTPUTS)
        m.d.comb += motion_next.eq(motion_acc)
        with m.If(stage4):
            m.d.comb += motion_next.eq(Mux(row_r == 0, 0, motion_acc) | Mux(fires, mutated[OUTPUT_SHIFT:], 0))
        m.d.sync += motion_acc.eq(motion_next)

        # -- evaluation: start at the slot's last cycle, collect at done -----------------------------
        eval_index = Signal(ib)
        eval_valid = Signal()
        eval_motion = Signal(N_OUTPUTS)
        start = breeding_slot & (tau == self.c_last) & child_valid
        m.d.comb += ev.start.eq(start)
        with m.If(start):
            m.d.sync += [eval_index.eq(child[:ib]), eval_valid.eq(1), eval_motion.eq(motion_next)]
        with m.Elif(ev.done):
            m.d.sync += eval_valid.eq(0)
        m.d.comb += [
            self.result_valid.eq(ev.done & eval_valid), self.result_index.eq(eval_index),
            self.result_eligible.eq(self.avoid_en & (eval_motion != self.avoid_motion)),
            self.crashes.eq(ev.crashes), self.loops.eq(ev.loops), self.distance.eq(ev.distance),
        ]
        return m


class Learner(wiring.Component):
    """The learning engine: ``config.lanes`` lanes, the population banks, the pass controller.

    Parameters
    ----------
    config : ga.hardware_ga.HardwareGAConfig
        Population, tournament, lanes and rates (constants of the circuit).
    distance_rule : str
        dist[a] of the lanes' evaluators (``ga.motions.DISTANCE_RULES``).

    Ports: see the module docstring (host protocol).
    """

    def __init__(self, config: hg.HardwareGAConfig, distance_rule: str = "covered"):
        if not isinstance(config, hg.HardwareGAConfig):
            raise TypeError(f"config must be a HardwareGAConfig, got {config!r}")
        self.config = config
        self.distance_rule = distance_rule
        ib = self.ib = index_bits(config.population)
        ports = {
            "pop_index": In(ib), "pop_row": In(ROW_INDEX_BITS), "pop_data": In(ROW_BITS),
            "pop_we": In(1), "pop_rdata": Out(ROW_BITS),
            "seed": In(32), "seed_we": In(1),
            "generations": In(16), "start": In(1),
            "ready": Out(1), "busy": Out(1), "done": Out(1), "evaluated": Out(1),
            "best_index": Out(ib), "best_score": Out(hg.SCORE_BITS),
            "best_crashes": Out(COUNT_BITS), "best_loops": Out(COUNT_BITS),
            "best_distance": Out(DISTANCE_BITS),
            "cycles": Out(32), "n_states": Out(COUNT_BITS),
            "avoid_en": In(1), "avoid_state": In(N_INPUTS), "avoid_motion": In(N_OUTPUTS),
            "escape_found": Out(1), "escape_index": Out(ib), "escape_score": Out(hg.SCORE_BITS),
            "escape_crashes": Out(COUNT_BITS), "escape_loops": Out(COUNT_BITS),
            "escape_distance": Out(DISTANCE_BITS),
        }
        ports.update(_model_ports())
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg, ib, L, S = self.config, self.ib, self.config.lanes, self.config.slots
        lanes = [Lane(cfg, j, self.distance_rule) for j in range(L)]
        for j, lane in enumerate(lanes):
            m.submodules[f"lane{j}"] = lane
            _broadcast(m, self, lane)
        banks = []
        for r in range(N_ROWS):
            mem = Memory(shape=ROW_BITS, depth=2 << ib, init=[])
            m.submodules[f"bank{r}"] = mem
            banks.append((mem.read_port(), mem.write_port()))

        n = lanes[0].n_states
        m.d.comb += self.n_states.eq(n)
        c_last = Signal(TAU_BITS)
        breed = 2 * cfg.tournament + 1 + N_ROWS + hg.ROW_LATENCY  # ga.hardware_ga.slot_cycles
        m.d.comb += c_last.eq(Mux(n + 2 > breed, n + 1, breed - 1))

        # -- pass constants ----------------------------------------------------------------------
        cur_buf = Signal()
        best_prev = Signal(ib)
        running = Signal()
        for lane in lanes:
            m.d.comb += [lane.c_last.eq(c_last), lane.copy_mode.eq(~self.evaluated),
                         lane.cur_buf.eq(cur_buf), lane.best_prev.eq(best_prev),
                         lane.seed.eq(self.seed), lane.seed_we.eq(self.seed_we & self.ready),
                         lane.avoid_en.eq(self.avoid_en), lane.avoid_state.eq(self.avoid_state),
                         lane.avoid_motion.eq(self.avoid_motion)]

        # -- the slot counter and its delay line (lane j sees it j cycles late) ------------------------
        tau = Signal(TAU_BITS)
        slot = Signal(range(S + 1))
        active = Signal()
        stage = (tau, slot, active)
        for j, lane in enumerate(lanes):
            m.d.comb += [lane.tau.eq(stage[0]), lane.slot.eq(stage[1]), lane.active.eq(stage[2])]
            delayed = (Signal(TAU_BITS, name=f"tau_d{j + 1}"), Signal(range(S + 1), name=f"slot_d{j + 1}"),
                       Signal(name=f"active_d{j + 1}"))
            m.d.sync += [d.eq(s) for d, s in zip(delayed, stage)]
            stage = delayed

        # -- banks: the lanes while running, the host otherwise -----------------------------------------
        # M = bank_groups(config) groups, group k holding the banks of rows k, k + M, ...: the
        # lanes ask M consecutive rows at most in a cycle, so each group serves one lane a cycle
        # and has one request register (address), one write register and one read multiplexer,
        # whatever the lanes: a lane's row comes from the group of its row through an M:1
        # multiplexer, and each bank's read data goes to its group's multiplexer only (the host
        # reads through the same multiplexers). Every path between a lane and a bank starts or
        # ends at a register.
        n_groups = bank_groups(cfg)
        groups = [list(range(k, N_ROWS, n_groups)) for k in range(n_groups)]
        q_bits = max(1, (len(groups[0]) - 1).bit_length())
        residue = Array(Const(r % n_groups, range(n_groups)) for r in range(N_ROWS))
        quotient = Array(Const(r // n_groups, q_bits) for r in range(N_ROWS))
        host = ~running
        host_row_r = Signal(ROW_INDEX_BITS)
        m.d.sync += host_row_r.eq(self.pop_row)
        host_addr = Cat(self.pop_index, cur_buf)
        group_out = []
        for k, rows in enumerate(groups):
            # stage 2: the request of the lane whose row is in the group; stage 3: its data
            req_q, req_addr = Signal(q_bits, name=f"g{k}_rd_q"), Signal(ib + 1, name=f"g{k}_rd_addr")
            wr_en_r, wr_q = Signal(name=f"g{k}_wr_en"), Signal(q_bits, name=f"g{k}_wr_q")
            wr_addr_r, wr_data_r = Signal(ib + 1, name=f"g{k}_wr_addr"), Signal(ROW_BITS, name=f"g{k}_wr_data")
            q, addr, wen, wq, waddr, wdata = (Const(0, q_bits), Const(0, ib + 1), Const(0, 1),
                                              Const(0, q_bits), Const(0, ib + 1), Const(0, ROW_BITS))
            for lane in lanes:
                hit = lane.rd_en & (residue[lane.rd_row] == k)
                q = q | Mux(hit, quotient[lane.rd_row], 0)
                addr = addr | Mux(hit, lane.rd_addr, 0)
                whit = lane.wr_en & (residue[lane.wr_row] == k)
                wen = wen | whit
                wq = wq | Mux(whit, quotient[lane.wr_row], 0)
                waddr = waddr | Mux(whit, lane.wr_addr, 0)
                wdata = wdata | Mux(whit, lane.wr_data, 0)
            m.d.sync += [req_q.eq(q), req_addr.eq(addr), wr_en_r.eq(wen), wr_q.eq(wq),
                         wr_addr_r.eq(waddr), wr_data_r.eq(wdata)]
            sel = Signal(q_bits, name=f"g{k}_sel")  # the bank whose data is read this cycle
            m.d.sync += sel.eq(Mux(host, quotient[self.pop_row], req_q))
            out = Signal(ROW_BITS, name=f"g{k}_out")
            m.d.comb += out.eq(Array(banks[r][0].data for r in rows)[sel])
            group_out.append(out)
            for i, r in enumerate(rows):
                rd, wr = banks[r]
                host_we = self.pop_we & (self.pop_row == r) & self.ready
                m.d.comb += [
                    rd.addr.eq(Mux(host, host_addr, req_addr)),
                    wr.addr.eq(Mux(host, host_addr, wr_addr_r)),
                    wr.data.eq(Mux(host, self.pop_data, wr_data_r)),
                    wr.en.eq(Mux(host, host_we, wr_en_r & (wr_q == i))),
                ]
        group_out = Array(group_out)
        m.d.comb += self.pop_rdata.eq(group_out[residue[host_row_r]])
        for j, lane in enumerate(lanes):  # stage 3 -> 4: the lane's row from its group
            got = Signal(ROW_BITS, name=f"lane{j}_row")
            m.d.sync += got.eq(Mux(lane.data_en, group_out[residue[lane.data_row]], 0))
            m.d.comb += lane.rd_data.eq(got)

        # -- results: score, score replicas, running best -------------------------------------------
        d = MAX_MOTION_DISTANCE_MM
        res_valid, res_eligible = Const(0, 1), Const(0, 1)
        res_index, res_c, res_l, res_d = Const(0, ib), Const(0, COUNT_BITS), Const(0, COUNT_BITS), Const(0, DISTANCE_BITS)
        for lane in lanes:
            v = lane.result_valid
            res_valid = res_valid | v
            res_eligible = res_eligible | (v & lane.result_eligible)
            res_index = res_index | Mux(v, lane.result_index, 0)
            res_c = res_c | Mux(v, lane.crashes, 0)
            res_l = res_l | Mux(v, lane.loops, 0)
            res_d = res_d | Mux(v, lane.distance, 0)
        # the result bus, registered (RESULT_LATENCY): one lane finishes per cycle at most
        res = [(res_valid, Signal(name="res_valid_q")), (res_eligible, Signal(name="res_eligible_q")),
               (res_index, Signal(ib, name="res_index_q")), (res_c, Signal(COUNT_BITS, name="res_c_q")),
               (res_l, Signal(COUNT_BITS, name="res_l_q")), (res_d, Signal(DISTANCE_BITS, name="res_d_q"))]
        m.d.sync += [q.eq(v) for v, q in res]
        res_valid, res_eligible, res_index, res_c, res_l, res_d = (q for _, q in res)
        res_score = Signal(hg.SCORE_BITS)
        m.d.comb += res_score.eq(5 * d * (n - res_c) + 4 * d * (n - res_l) + res_d)
        for lane in lanes:
            m.d.comb += [lane.score_addr.eq(Cat(res_index, ~cur_buf)), lane.score_data.eq(res_score),
                         lane.score_we.eq(res_valid)]
        with m.If(res_valid & ((res_index == 0) | (res_score > self.best_score))):
            m.d.sync += [self.best_index.eq(res_index), self.best_score.eq(res_score),
                         self.best_crashes.eq(res_c), self.best_loops.eq(res_l),
                         self.best_distance.eq(res_d)]
        pass_start = Signal()
        with m.If(pass_start):
            m.d.sync += self.escape_found.eq(0)
        with m.Elif(res_eligible & (~self.escape_found | (res_score > self.escape_score))):
            m.d.sync += [self.escape_found.eq(1), self.escape_index.eq(res_index),
                         self.escape_score.eq(res_score), self.escape_crashes.eq(res_c),
                         self.escape_loops.eq(res_l), self.escape_distance.eq(res_d)]

        # -- pass controller ----------------------------------------------------------------------
        lanes_ready = Const(1, 1)
        for lane in lanes:
            lanes_ready = lanes_ready & lane.ready
        passes_left = Signal(16)
        drain = Signal(range(L + hg.RESULT_LATENCY + 1))
        with m.If(self.ready & self.pop_we):
            m.d.sync += self.evaluated.eq(0)
        m.d.sync += self.done.eq(0)
        with m.If(running):
            m.d.sync += self.cycles.eq(self.cycles + 1)
        with m.FSM():
            with m.State("Idle"):
                m.d.comb += self.ready.eq(lanes_ready)
                with m.If(self.start & lanes_ready & (self.generations != 0)):
                    m.d.comb += pass_start.eq(1)
                    m.d.sync += [passes_left.eq(self.generations), tau.eq(0), slot.eq(0),
                                 active.eq(1), self.cycles.eq(0)]
                    m.next = "Run"
            with m.State("Run"):
                m.d.comb += [self.busy.eq(1), running.eq(1)]
                with m.If(tau == c_last):
                    m.d.sync += tau.eq(0)
                    with m.If(slot == S):
                        m.d.sync += [active.eq(0), drain.eq(0)]
                        m.next = "Drain"
                    with m.Else():
                        m.d.sync += slot.eq(slot + 1)
                with m.Else():
                    m.d.sync += tau.eq(tau + 1)
            with m.State("Drain"):
                # the lanes behind lane 0 finish their last slot
                m.d.comb += [self.busy.eq(1), running.eq(1)]
                m.d.sync += drain.eq(drain + 1)
                with m.If(drain == L + hg.RESULT_LATENCY - 1):
                    m.d.sync += [cur_buf.eq(~cur_buf), best_prev.eq(self.best_index),
                                 self.evaluated.eq(1), passes_left.eq(passes_left - 1)]
                    with m.If(passes_left == 1):
                        m.d.sync += self.done.eq(1)
                        m.next = "Idle"
                    with m.Else():
                        m.d.comb += pass_start.eq(1)
                        m.d.sync += [tau.eq(0), slot.eq(0), active.eq(1)]
                        m.next = "Run"
        return m
