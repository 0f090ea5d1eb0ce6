// Properties of EvaluatorEHW (hdl/evaluator_ehw.py, double-buffered), proven by temporal
// induction (formal/proofs.py, proof evaluator_ehw). The harness drives every input freely; the
// base case is a reset in the first cycle.
//
// RAM abstraction: the world-model RAM is removed and its read data (`ram_data`, the entry the
// trace engine reads) is a free input in every cycle, so the proof covers every world model the
// host could have written at once, of any size, rather than the few a bounded run reaches. The
// one assumption on it is the world-model invariant of ga.world_model (observe() adds both the
// state and the next state to S): a known, non-crash entry read while tracing leads to a state
// of S. What the RAM abstraction does not cover: that the entry read is the one written (the
// counts crashes/loops/distance are checked against the NumPy reference in simulation only).
`include "dut.vh"

module evaluator_props #(
    parameter K = 50,  // rows (EvaluatorEHW(k))
    parameter A = 6    // row address bits
) (
    input wire         clk,
    input wire         rst,
    input wire [A-1:0] row_addr,
    input wire [18:0]  row_data,
    input wire         row_we,
    input wire [7:0]   model_state,
    input wire [2:0]   model_motion,
    input wire [7:0]   model_next,
    input wire         model_crash,
    input wire         model_valid,
    input wire         model_we,
    input wire [7:0]   rate_state,
    input wire [2:0]   rate_motion,
    input wire [`RATE_BITS-1:0] rate_code,
    input wire         rate_we,
    input wire [7:0]   state_value,
    input wire         state_we,
    input wire         clear,
    input wire         reflex_en,
    input wire         start,
    input wire [`ENTRY_BITS-1:0] ram_data,  // the RAM's read data (RAM abstraction, see above)
    input wire [`RATE_BITS-1:0] rate_data   // the failure-rate RAM's read data (the same)
);
    localparam W = 19;
    localparam RAM_DEPTH = 2048;

    wire        ready, busy, done;
    wire [8:0]  crashes, loops, n_states;
    wire [15:0] distance, fails, cycles;
    evaluator_ehw dut (`DUT_PORTS);

    // The DUT's internal registers and wires, connected by formal/ports.py after flatten.
    (* keep *) wire [2:0]     probe_fsm;
    (* keep *) wire [10:0]    probe_clear_addr;
    (* keep *) wire [255:0]   probe_in_set;
    (* keep *) wire [255:0]   probe_tested;
    (* keep *) wire [15:0]    probe_acc_cycles;
    (* keep *) wire [K*W-1:0] probe_arch;
    (* keep *) wire           probe_tracing;
    (* keep *) wire           probe_wr_en;
    (* keep *) wire [10:0]    probe_wr_addr;
    (* keep *) wire [`ENTRY_BITS-1:0] probe_wr_data;
    (* keep *) wire           probe_rate_wr_en;
    (* keep *) wire [10:0]    probe_rate_wr_addr;
    (* keep *) wire [`RATE_BITS-1:0] probe_rate_wr_data;

    // The RAM word of the model port's entry (hdl.ports.ModelEntry, macros from formal/ports.py):
    // it moves when valid and not a crash; otherwise its next field codes crash or unknown.
    wire entry_moves = model_valid && !model_crash;

    wire idle     = probe_fsm == `FSM_IDLE;
    wire in_boot  = probe_fsm == `FSM_BOOT;
    wire in_clear = probe_fsm == `FSM_CLEAR;
    wire in_begin = probe_fsm == `FSM_BEGIN;
    wire in_trace = probe_fsm == `FSM_TRACE;
    wire evaluating = in_begin || in_trace;

    // v has exactly one bit set
    function one_hot(input [255:0] v);
        one_hot = v != 0 && (v & (v - 1)) == 0;
    endfunction

    // -- assumption: the world-model invariant on the entries the trace engine reads ----------
    always @* begin
        if (probe_tracing && ram_data[`ENTRY_MOVES])  // valid, no crash
            assume (probe_in_set[ram_data[`ENTRY_NEXT]]);
    end

    // -- ghost state: last cycle's values, counters since reset and since start ----------------
    wire accept_start = idle && start && !clear;
    reg         rst_q, start_q, clear_q, state_we_q, done_q, idle_q, evaluating_q;
    reg [7:0]   state_value_q;
    reg [255:0] in_set_q, tested_q;
    reg [8:0]   n_states_q, crashes_q, loops_q;
    reg [15:0]  distance_q, fails_q, cycles_q;
    reg [K*W-1:0] arch_q;
    reg [11:0]  since_reset;   // cycles since the first cycle after a reset (saturates)
    reg         seen_ready;    // ready was high since that reset
    reg [15:0]  elapsed;       // clock edges after the edge that accepted the start
    (* keep *) reg count_ok;   // the N + 1 claim (for the bounded proof)
    always @(posedge clk) begin
        rst_q <= rst;
        start_q <= start;
        clear_q <= clear;
        state_we_q <= state_we;
        state_value_q <= state_value;
        done_q <= done;
        idle_q <= idle;
        evaluating_q <= evaluating;
        in_set_q <= probe_in_set;
        tested_q <= probe_tested;
        n_states_q <= n_states;
        crashes_q <= crashes;
        loops_q <= loops;
        distance_q <= distance;
        fails_q <= fails;
        cycles_q <= cycles;
        arch_q <= probe_arch;
        if (rst) begin
            since_reset <= 0;
            seen_ready <= 0;
            elapsed <= 0;
        end else begin
            if (since_reset != 12'hfff)
                since_reset <= since_reset + 1;
            if (ready)
                seen_ready <= 1;
            if (accept_start)
                elapsed <= 0;
            else if (evaluating)
                elapsed <= elapsed + 1;
        end
    end

    always @* begin
        // handshake outputs are the FSM's; done comes with ready
        assert (ready == idle);
        assert (busy == !ready);
        if (done)
            assert (idle);
        // reset: Boot (the sweep follows), S empty, no done
        if (rst_q)
            assert (in_boot && probe_in_set == 0 && n_states == 0 && !done);

        if (!rst_q) begin
            // (1) start is ignored while busy: an evaluation begins only from a start accepted
            //     when ready, and only then is the shadow copied into the active configuration.
            if (in_begin)
                assert (idle_q && start_q && !clear_q);
            if (!(idle_q && start_q && !clear_q))
                assert (probe_arch == arch_q);

            // (2) done is high for exactly one cycle, right after an evaluation, with ready.
            if (done)
                assert (!done_q && evaluating_q);

            // (3) results change only at the edge that raises done, and hold until the next.
            if (!done)
                assert (crashes == crashes_q && loops == loops_q && distance == distance_q
                        && fails == fails_q && cycles == cycles_q);

            // (4) model writes and state additions only when ready: a RAM write is the host's
            //     (exactly the entry on the model port, coded) while ready, the Clear sweep's zero
            //     otherwise; S and |S| change only by an addition or a clear accepted when ready.
            if (!(idle_q && (state_we_q || clear_q)))
                assert (probe_in_set == in_set_q && n_states == n_states_q);
            if (idle_q && clear_q)
                assert (probe_in_set == 0 && n_states == 0);
            if (idle_q && state_we_q && !clear_q)
                assert (probe_in_set == (in_set_q | (256'b1 << state_value_q))
                        && n_states == n_states_q + !in_set_q[state_value_q]);
        end
        if (probe_wr_en)
            assert (idle ? (probe_wr_addr == {model_state, model_motion}
                            && probe_wr_data[`ENTRY_MOVES] == entry_moves
                            && probe_wr_data[`ENTRY_NEXT] == (entry_moves ? model_next :
                                                              model_valid ? `ENTRY_CRASH : `ENTRY_UNKNOWN))
                         : (in_clear && probe_wr_data == 0 && probe_wr_addr == probe_clear_addr));
        if (idle && model_we)
            assert (probe_wr_en);
        //     The same for the failure-rate codes: the host's code while ready, the Clear sweep's
        //     prior (a pair never executed) otherwise.
        if (probe_rate_wr_en)
            assert (idle ? (probe_rate_wr_addr == {rate_state, rate_motion} && probe_rate_wr_data == rate_code)
                         : (in_clear && probe_rate_wr_data == `PRIOR_CODE
                            && probe_rate_wr_addr == probe_clear_addr));
        if (idle && rate_we)
            assert (probe_rate_wr_en);
        if (in_clear)
            assert (probe_rate_wr_en);

        // (5) ready within 2,049 cycles of reset: Boot, then Clear sweeps address
        //     since_reset - 1 (each of the 2,048 once, in order, writing 0), then Idle.
        if (!seen_ready) begin
            assert (since_reset <= 2049);
            assert (in_boot ? since_reset == 0 :
                    in_clear ? (since_reset >= 1 && since_reset <= RAM_DEPTH
                                && probe_clear_addr == since_reset - 1) :
                    (idle && since_reset == 2049));
        end

        // (6) the cycle count. Proven here, for every model: the evaluation (Begin, then Trace
        //     cycles) tests nothing in Begin and one state of S in the first Trace cycle; each
        //     further Trace cycle adds exactly one untested state of S to the tested set; S is
        //     frozen; done comes when the tested set is S, and then cycles = the edges from the
        //     edge that accepted start. Hence (counting, docs/formal.md): a model of N states
        //     has N Trace cycles, done N + 1 edges after that edge, cycles = N + 1. The count
        //     itself is checked by the bounded proof evaluator_ehw_count (formal/proofs.py).
        if (in_begin)
            assert (probe_tested == 0 && probe_acc_cycles == 0 && elapsed == 0);
        if (in_trace)
            assert ((probe_tested & ~probe_in_set) == 0 && probe_tested != 0
                    && probe_acc_cycles == elapsed);
        if (!rst_q && in_trace) begin
            assert (evaluating_q && probe_in_set == in_set_q && n_states == n_states_q);
            assert (one_hot(probe_tested & ~tested_q) && (tested_q & ~probe_tested) == 0);
        end
        if (!rst_q && done)
            assert (probe_tested == probe_in_set && cycles == elapsed);
        // the same, counted: with cycles = |S| + 1 (the bounded proof checks this one)
        count_ok = !(done && !rst_q) || (cycles == n_states + 1 && elapsed == n_states + 1);
    end
endmodule
