"""The learning engine of SPEC section 12: the hardware GA and L evaluator lanes on one chip.

Bit-exact with ``ga.hardware_ga`` (the algorithm, the random source, the draw schedule and the
integer score are defined there; this module only says how the hardware does it).

Datapath
--------
- ``bank[r]`` (r = 0..49): row r of every individual of both population buffers, one
  ``Memory(shape=19, depth=2 * 2^ceil(log2 P))`` each, address ``Cat(index, buffer)``. One
  synchronous read port and one write port per bank: in a pass the lanes read the parents from
  the current buffer and write the children into the other one.
- ``lane[j]`` (``hdl.learner_lane.Lane``): an ``EvaluatorEHW`` (its own copy of the world-model RAM
  and of the failure-rate RAM, state set and trace engine: every model and rate write goes to
  every lane, so the copies stay identical; its ``fails`` is the child's F), the
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
- A global slot counter (``tau`` in 0..C-1, ``slot`` in 0..S, and ``base`` = slot * L, counted so
  that a lane's child index slot * L + j is an adder, not a multiplier: with L = 7 the product
  was the critical path of the routed build) whose value reaches lane j through
  j registers: lane j runs j cycles behind lane 0. A lane asks bank r in the cycle it draws its
  row r, so two lanes never ask the same group in one cycle (their rows differ by their lane
  distance, less than M); the same holds for the bank writes, for the score writes and for the
  running best (one lane finishes per cycle, in the children's order).
- The result bus (the finishing lane's index and counts) is registered before the score, the
  running best and the score replicas (``ga.hardware_ga.RESULT_LATENCY`` = 1 cycle of drain).
  The score (``ga.hardware_ga.score``, less the fail count F) is signed (``SCORE_BITS``), and so
  are the replicas, the tournaments' and the running bests' comparisons.

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
World model: the ``model`` port (``hdl.ports.ModelWriteSignature``), the failure-rate port
``rate`` (``hdl.ports.RateWriteSignature``: one code a cycle; CLEAR and reset write
``PRIOR_CODE`` to every code), ``state_*`` and ``clear`` of ``EvaluatorEHW``, broadcast to every
lane. Population: ``pop_index``, ``pop_row``, ``pop_data``, ``pop_we`` write a row of the
current buffer (and mark the population unevaluated: the next pass only evaluates it);
``pop_index``, ``pop_row`` read a row (``pop_rdata``, one cycle later). ``seed`` + ``seed_we``
seed every generator (``ga.hardware_ga.lane_seeds``). ``generations`` + ``start``: run that many
passes; ``done`` pulses at the end; ``best_*`` hold the best of the last pass (index in the current
buffer, score, counts and ``best_fails``) and ``cycles`` the busy cycles of the last run. With ``avoid_en`` (and
``avoid_state``, ``avoid_motion`` held during the run) ``escape_*`` hold the first child of
highest score whose array motion in ``avoid_state`` is not ``avoid_motion`` (``escape_found``:
there is one); each lane ORs the outputs of the rows firing in that state as they stream in.
"""

from __future__ import annotations

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ga import hardware_ga as hg
from ga.fail_rates import FAIL_BITS
from ga.genome import N_ROWS, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE, MAX_MOTION_DISTANCE_MM, N_INPUTS, N_OUTPUTS
from hdl.learner_lane import ROW_INDEX_BITS, TAU_BITS, Lane, broadcast, index_bits, model_ports
from hdl.ports import COUNT_BITS, DISTANCE_BITS

__all__ = ["Lane", "Learner", "bank_groups", "index_bits"]


def bank_groups(config: hg.HardwareGAConfig) -> int:
    """The number M of bank groups: group k holds the banks of rows k, k + M, ... .

    Lane j draws row r - j when lane 0 draws row r (its slot counter runs j cycles behind), so in
    one slot the rows asked in a cycle are consecutive and M = L groups are enough for each group
    to serve one lane a cycle. Lanes in different slots could both be in their row phase only if
    a slot were shorter than 50 + L - 1 cycles (C >= 2T + 54: L > 2T + 5); then one group per
    row (M = 50: the lanes' rows differ by less than C)."""
    return config.lanes if config.lanes <= 2 * config.tournament + 5 else N_ROWS


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

    def __init__(self, config: hg.HardwareGAConfig, distance_rule: str = DEFAULT_DISTANCE_RULE):
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
            "best_index": Out(ib), "best_score": Out(signed(hg.SCORE_BITS)),
            "best_crashes": Out(COUNT_BITS), "best_loops": Out(COUNT_BITS),
            "best_distance": Out(DISTANCE_BITS), "best_fails": Out(FAIL_BITS),
            "cycles": Out(32), "n_states": Out(COUNT_BITS),
            "avoid_en": In(1), "avoid_state": In(N_INPUTS), "avoid_motion": In(N_OUTPUTS),
            "escape_found": Out(1), "escape_index": Out(ib), "escape_score": Out(signed(hg.SCORE_BITS)),
            "escape_crashes": Out(COUNT_BITS), "escape_loops": Out(COUNT_BITS),
            "escape_distance": Out(DISTANCE_BITS), "escape_fails": Out(FAIL_BITS),
        }
        ports.update(model_ports())
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg, ib, L, S = self.config, self.ib, self.config.lanes, self.config.slots
        lanes = [Lane(cfg, j, self.distance_rule) for j in range(L)]
        for j, lane in enumerate(lanes):
            m.submodules[f"lane{j}"] = lane
            broadcast(m, self, lane)
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
        base = Signal(range(S * L + 1))  # slot * L, counted (no multiplier): child = base + j
        active = Signal()
        stage = (tau, slot, base, active)
        for j, lane in enumerate(lanes):
            m.d.comb += [lane.tau.eq(stage[0]), lane.slot.eq(stage[1]), lane.base.eq(stage[2]),
                         lane.active.eq(stage[3])]
            delayed = (Signal(TAU_BITS, name=f"tau_d{j + 1}"), Signal(range(S + 1), name=f"slot_d{j + 1}"),
                       Signal(range(S * L + 1), name=f"base_d{j + 1}"), Signal(name=f"active_d{j + 1}"))
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
        res_f = Const(0, FAIL_BITS)
        for lane in lanes:
            v = lane.result_valid
            res_valid = res_valid | v
            res_eligible = res_eligible | (v & lane.result_eligible)
            res_index = res_index | Mux(v, lane.result_index, 0)
            res_c = res_c | Mux(v, lane.crashes, 0)
            res_l = res_l | Mux(v, lane.loops, 0)
            res_d = res_d | Mux(v, lane.distance, 0)
            res_f = res_f | Mux(v, lane.fails, 0)
        # the result bus, registered (RESULT_LATENCY): one lane finishes per cycle at most
        res = [(res_valid, Signal(name="res_valid_q")), (res_eligible, Signal(name="res_eligible_q")),
               (res_index, Signal(ib, name="res_index_q")), (res_c, Signal(COUNT_BITS, name="res_c_q")),
               (res_l, Signal(COUNT_BITS, name="res_l_q")), (res_d, Signal(DISTANCE_BITS, name="res_d_q")),
               (res_f, Signal(FAIL_BITS, name="res_f_q"))]
        m.d.sync += [q.eq(v) for v, q in res]
        res_valid, res_eligible, res_index, res_c, res_l, res_d, res_f = (q for _, q in res)
        res_score = Signal(signed(hg.SCORE_BITS))  # ga.hardware_ga.score: negative when F outweighs the rest
        m.d.comb += res_score.eq(5 * d * (n - res_c) + 4 * d * (n - res_l) + res_d - res_f)
        for lane in lanes:
            m.d.comb += [lane.score_addr.eq(Cat(res_index, ~cur_buf)), lane.score_data.eq(res_score),
                         lane.score_we.eq(res_valid)]
        with m.If(res_valid & ((res_index == 0) | (res_score > self.best_score))):
            m.d.sync += [self.best_index.eq(res_index), self.best_score.eq(res_score),
                         self.best_crashes.eq(res_c), self.best_loops.eq(res_l),
                         self.best_distance.eq(res_d), self.best_fails.eq(res_f)]
        pass_start = Signal()
        with m.If(pass_start):
            m.d.sync += self.escape_found.eq(0)
        with m.Elif(res_eligible & (~self.escape_found | (res_score > self.escape_score))):
            m.d.sync += [self.escape_found.eq(1), self.escape_index.eq(res_index),
                         self.escape_score.eq(res_score), self.escape_crashes.eq(res_c),
                         self.escape_loops.eq(res_l), self.escape_distance.eq(res_d),
                         self.escape_fails.eq(res_f)]

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
                    m.d.sync += [passes_left.eq(self.generations), tau.eq(0), slot.eq(0), base.eq(0),
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
                        m.d.sync += [slot.eq(slot + 1), base.eq(base + L)]
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
                        m.d.sync += [tau.eq(0), slot.eq(0), base.eq(0), active.eq(1)]
                        m.next = "Run"
        return m
