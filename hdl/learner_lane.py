"""One evaluator lane of the learning engine (``hdl.learner``): its evaluator, generators,
tournament, row mutation and escape accumulator. The lane's schedule and its place in the
datapath are in ``hdl.learner``'s docstring; the algorithm in ``ga.hardware_ga``'s.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ga import hardware_ga as hg
from ga.fail_rates import FAIL_BITS
from ga.genome import N_ROWS, OUTPUT_SHIFT, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE, N_INPUTS, N_OUTPUTS
from ga.operators import CONTRADICTION, DONT_CARE, NEGATIVE, POSITIVE
from hdl.evaluator_ehw import EvaluatorEHW
from hdl.ports import COUNT_BITS, DISTANCE_BITS, ModelWriteSignature, RateWriteSignature, row_addr_bits

TAU_BITS = 10  # C <= max(258, 2T + 54) < 1024 for T <= 480
ROW_INDEX_BITS = row_addr_bits(N_ROWS)
# The evaluator's model-side inputs, broadcast from the learner to every lane's evaluator.
_MODEL_MEMBERS = ("state", "motion", "next", "crash", "valid", "we")  # of ModelWriteSignature
_RATE_MEMBERS = ("state", "motion", "code", "we")  # of RateWriteSignature
_STATE_PORTS = ("state_value", "state_we", "clear", "reflex_en")


def broadcast(m, source, sink):
    """Drive ``sink``'s model and rate ports and state inputs from ``source``'s (one writer, many
    copies: ``wiring.connect`` joins one port to one)."""
    m.d.comb += [getattr(sink.model, name).eq(getattr(source.model, name)) for name in _MODEL_MEMBERS]
    m.d.comb += [getattr(sink.rate, name).eq(getattr(source.rate, name)) for name in _RATE_MEMBERS]
    m.d.comb += [getattr(sink, name).eq(getattr(source, name)) for name in _STATE_PORTS]


def _xorshift(x):
    """One xorshift32 step as a 32-bit expression (``ga.hardware_ga.xorshift32``)."""
    x = (x ^ (x << 13))[:32]
    x = (x ^ (x >> 17))[:32]
    return (x ^ (x << 5))[:32]


def index_bits(population: int) -> int:
    return max(1, (population - 1).bit_length())


def model_ports():
    """The evaluator's world-model side: the model and failure-rate write ports and the state-set
    inputs."""
    return {"model": In(ModelWriteSignature()), "rate": In(RateWriteSignature()), "state_value": In(N_INPUTS),
            "state_we": In(1), "clear": In(1), "reflex_en": In(1)}


class Lane(wiring.Component):
    """One evaluator lane with its generators, tournament and row mutation (see the module
    docstring). ``index`` is the lane number j (its generators' salts).

    Ports: ``tau``, ``slot``, ``base`` (= slot * L), ``active`` (the slot counter as lane j sees it), ``c_last`` (C - 1),
    ``copy_mode``, ``cur_buf``, ``best_prev`` (pass constants), ``seed``/``seed_we``, the score
    replica's write port ``score_*``, the model port and state inputs (to the evaluator), the bank request
    ``rd_en``/``rd_row``/``rd_addr`` and the row ``data_row`` whose data is expected on
    ``rd_data`` this cycle, the bank write ``wr_*``, and the result ``result_valid``,
    ``result_index``, ``crashes``, ``loops``, ``distance``, ``fails``; ``n_states``, ``ready`` from the
    evaluator.
    """

    def __init__(self, config: hg.HardwareGAConfig, index: int, distance_rule: str = DEFAULT_DISTANCE_RULE):
        self.config = config
        self.index = index
        self.distance_rule = distance_rule
        ib = index_bits(config.population)
        self.ib = ib
        ports = {
            "tau": In(TAU_BITS), "slot": In(range(config.slots + 1)),
            "base": In(range(config.slots * config.lanes + 1)), "active": In(1),
            "c_last": In(TAU_BITS), "copy_mode": In(1), "cur_buf": In(1), "best_prev": In(ib),
            "seed": In(32), "seed_we": In(1),
            "score_addr": In(ib + 1), "score_data": In(signed(hg.SCORE_BITS)), "score_we": In(1),
            "rd_en": Out(1), "rd_row": Out(ROW_INDEX_BITS), "rd_addr": Out(ib + 1),
            "data_en": Out(1), "data_row": Out(ROW_INDEX_BITS), "rd_data": In(ROW_BITS),
            "wr_en": Out(1), "wr_row": Out(ROW_INDEX_BITS), "wr_addr": Out(ib + 1),
            "wr_data": Out(ROW_BITS),
            "result_valid": Out(1), "result_index": Out(ib),
            "crashes": Out(COUNT_BITS), "loops": Out(COUNT_BITS), "distance": Out(DISTANCE_BITS),
            "fails": Out(FAIL_BITS), "n_states": Out(COUNT_BITS), "ready": Out(1),
            "avoid_en": In(1), "avoid_state": In(N_INPUTS), "avoid_motion": In(N_OUTPUTS),
            "result_eligible": Out(1),
        }
        ports.update(model_ports())
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg, ib, T, P, L = self.config, self.ib, self.config.tournament, self.config.population, self.config.lanes
        ev = m.submodules.evaluator = EvaluatorEHW(double_buffer=True, distance_rule=self.distance_rule,
                                                   lookahead=True)
        broadcast(m, self, ev)
        m.d.comb += [self.n_states.eq(ev.n_states), self.ready.eq(ev.ready)]

        scores = m.submodules.scores = Memory(shape=signed(hg.SCORE_BITS), depth=2 << ib, init=[])
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
        m.d.comb += child.eq(self.base + self.index)  # base = slot * L, counted by the engine
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
        best_a, best_b = Signal(signed(hg.SCORE_BITS)), Signal(signed(hg.SCORE_BITS))  # signed compares
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
            self.fails.eq(ev.fails),
        ]
        return m
