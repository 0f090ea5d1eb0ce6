"""The learning board behind the host link: ``LearnerLinkTop`` (SPEC section 12, issue 14).

The controller board (``ControllerEHW``) and the learning engine (``hdl.learner.Learner``) behind
one UART host link (the protocol of ``hdl.link_protocol``): the ``ulx3s-learner`` bitstream of
``hdl.fpga``. Only observations (4 bytes), "learn G generations" (4 bytes) and the download
(119 bytes) travel during a run; the population goes down once (500 LOAD_GENOME frames).

Commands (``hdl.link_protocol.DESIGN_COMMANDS[Design.LEARNER]``):

- IDENTIFY (``p_max`` = the population), READ_COUNTERS (``evaluator_cycles``: the engine's cycles
  of every learn since reset);
- LOAD_CONTROLLER, SET_REFLEX (both boards), MOTION: the controller board, as on the others;
- OBSERVE, CLEAR: the world model, broadcast to every lane's copy (CLEAR also sets every
  failure-rate code to ``PRIOR_CODE``);
- WRITE_RATE (``RATE_REQUEST``): one failure-rate code (``ga.fail_rates``), broadcast to every
  lane's rate RAM when the engine is ready;
- LOAD_GENOME (``index`` < P): the rows go into population slot ``index`` as they arrive (the
  next LEARN's first generation only evaluates the population); a frame that fails after
  touching them is re-sent by the host, so the slot ends up whole;
- SEED (``SEED_REQUEST``): seed every generator (``ga.hardware_ga.lane_seeds``);
- LEARN (``LEARN_REQUEST`` -> ``LEARN_REPLY``): run ``generations`` passes, with the escape of
  (``avoid_state``, ``avoid_motion``) when ``avoid_en``; the reply (sent at ``done``) gives the
  download's slot, score (signed), counts, fail count, the engine's cycles and whether it is the
  escape child. A LEARN carrying the ``serial`` of the last executed one is not run again: its
  reply is re-sent (the protocol's commands are idempotent: a host may resend one whose reply it
  lost);
- READ_GENOME (``READ_GENOME_REQUEST``): the 119 genome bytes of slot ``index`` of the current
  population (50 row reads into a 950-bit register, then sent byte by byte).
"""

from amaranth.hdl import Cat, Mux, Signal

from ga.genome import GENOME_BITS, N_ROWS, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.controller_ehw import ControllerEHW
from hdl.learner import Learner
from hdl.link_protocol import (LEARN_REPLY, LEARN_REQUEST, LOAD_GENOME_REQUEST, READ_GENOME_REQUEST,
                               SEED_REQUEST, Command, Design, Status, genome_bytes, layout_bytes)
from hdl.link_tops import _controller_states, _LinkTop, _Ports, _state
from hdl.uart import DEFAULT_BAUD


class LearnerLinkTop(_LinkTop):
    """``ControllerEHW`` + ``Learner(config)`` behind the host link (a ULX3S-85F).

    Parameters
    ----------
    clk_freq_hz : float; baud : float (default 115,200)
    config : ga.hardware_ga.HardwareGAConfig
        The engine's population, tournament, lanes and rates (constants of the circuit).
    distance_rule : str
    """

    DESIGN = Design.LEARNER

    def __init__(self, clk_freq_hz: float, baud: float = DEFAULT_BAUD, *, config,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, **kwargs):
        self.config = config
        self.distance_rule = distance_rule
        self.P_MAX = config.population
        super().__init__(clk_freq_hz, baud, distance_rule=distance_rule,
                         **{f"ga_{k}": v for k, v in config.to_dict().items()}, **kwargs)

    def _boards(self, m, link):
        ctl = self._ctl = m.submodules.ctl = ControllerEHW()
        eng = self._eng = m.submodules.learner = Learner(self.config, self.distance_rule)
        self._reflex = Signal()
        link.rows_for(m, Command.LOAD_CONTROLLER, ctl.row)
        m.d.comb += [ctl.reflex_en.eq(self._reflex), eng.reflex_en.eq(self._reflex)]
        # LOAD_GENOME: rows straight into the banks as the assembler makes them
        index = link.args_as(LOAD_GENOME_REQUEST).index
        self._read_row = Signal(range(N_ROWS + 1))
        self._reading = Signal()
        m.d.comb += [
            eng.pop_index.eq(Mux(self._reading, link.args_as(READ_GENOME_REQUEST).index, index)),
            eng.pop_row.eq(Mux(self._reading, self._read_row, link.asm.row.addr)),
            eng.pop_data.eq(link.asm.row.data),
            eng.pop_we.eq(link.writes(Command.LOAD_GENOME) & (index < self.P_MAX)),
        ]
        # READ_GENOME: the rows shift in (row 0 ends at bit 0), the sender reads them by byte
        genome = self._genome = Signal(8 * genome_bytes())
        self._shift = Signal()
        with m.If(self._shift):
            m.d.sync += genome[:GENOME_BITS].eq(Cat(genome[ROW_BITS:GENOME_BITS], eng.pop_rdata))
        with m.If(link.command == Command.READ_GENOME.value):
            m.d.comb += link.snd.byte.eq(genome.word_select(link.snd.index[:7], 8))

    def _states(self, m, link):
        eng = self._eng
        _controller_states(m, link, _Ports(x=self._ctl.x, motion=self._ctl.motion),
                           commit=self._ctl.commit, reflex=[self._reflex])
        ev = _Ports(model=eng.model, rate=eng.rate, state_value=eng.state_value, state_we=eng.state_we,
                    clear=eng.clear, ready=eng.ready)
        self._model_states(m, link, ev)
        self._rate_states(m, link, ev)
        with m.State(_state(Command.LOAD_GENOME)):
            with m.If(link.args_as(LOAD_GENOME_REQUEST).index >= self.P_MAX):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                link.answer(m, Status.OK)
        with m.State(_state(Command.SEED)):
            with m.If(eng.ready):
                m.d.comb += [eng.seed.eq(link.args_as(SEED_REQUEST).seed), eng.seed_we.eq(1)]
                link.answer(m, Status.OK)
        self._learn_states(m, link, eng)
        with m.State(_state(Command.READ_GENOME)):
            with m.If(link.args_as(READ_GENOME_REQUEST).index >= self.P_MAX):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                m.d.sync += self._read_row.eq(0)
                m.next = "ReadRows"
        with m.State("ReadRows"):
            # pop_row = r this cycle; row r - 1 is on pop_rdata (the banks' read is synchronous)
            m.d.comb += [self._reading.eq(1), self._shift.eq(self._read_row != 0)]
            m.d.sync += self._read_row.eq(self._read_row + 1)
            with m.If(self._read_row == N_ROWS):
                link.answer(m, Status.OK, genome_bytes())

    def _learn_states(self, m, link, eng):
        req = link.args_as(LEARN_REQUEST)
        last_serial = Signal(8)
        result = Signal(8 * layout_bytes(LEARN_REPLY))  # the last executed learn's reply
        reply = LEARN_REPLY(result)
        avoid_en, avoid_state, avoid_motion = Signal(), Signal.like(eng.avoid_state), Signal.like(eng.avoid_motion)
        generations = Signal.like(req.generations)
        m.d.comb += [eng.avoid_en.eq(avoid_en), eng.avoid_state.eq(avoid_state),
                     eng.avoid_motion.eq(avoid_motion), eng.generations.eq(generations),
                     link.counters.cycles.eq(reply.cycles)]
        with m.State(_state(Command.LEARN)):
            with m.If(req.serial == last_serial):
                m.d.sync += link.reply[:len(result)].eq(result)
                link.answer(m, Status.OK, layout_bytes(LEARN_REPLY))
            with m.Elif(req.generations == 0):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Elif(eng.ready):
                m.d.sync += [avoid_en.eq(req.avoid_en), avoid_state.eq(req.avoid_state),
                             avoid_motion.eq(req.avoid_motion), generations.eq(req.generations),
                             last_serial.eq(req.serial)]
                m.next = "LearnStart"
        with m.State("LearnStart"):
            m.d.comb += eng.start.eq(1)
            m.next = "LearnWait"
        with m.State("LearnWait"):
            with m.If(eng.done):
                # the escape child, when there is one; escaped: it is not the best itself
                # (ga.hardware_ga: download_index != best_index)
                found = avoid_en & eng.escape_found
                escaped = found & (eng.escape_index != eng.best_index)
                pick = lambda name: Mux(found, getattr(eng, f"escape_{name}"), getattr(eng, f"best_{name}"))  # noqa: E731
                m.d.sync += [reply.cycles.eq(eng.cycles), reply.index.eq(pick("index")),
                             reply.score.eq(pick("score")), reply.crashes.eq(pick("crashes")),
                             reply.loops.eq(pick("loops")), reply.distance.eq(pick("distance")),
                             reply.fails.eq(pick("fails")), reply.escaped.eq(escaped)]
                m.next = "LearnReply"
        with m.State("LearnReply"):
            # READ_COUNTERS' evaluator_cycles: the reply register holds until the next learn's end
            m.d.comb += link.counters.add_cycles.eq(1)
            m.d.sync += link.reply[:len(result)].eq(result)
            link.answer(m, Status.OK, layout_bytes(LEARN_REPLY))

