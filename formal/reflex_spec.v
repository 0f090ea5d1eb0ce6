// The reflex of SPEC section 6, written from the spec text alone: "when no obstacle is perceived
// (x0..x5 all 0) the motion is fixed: sector front -> forward, left -> turn left, right -> turn
// right, back -> turn left." Sector code x6 + 2 x7 (SPEC section 4): 0 front, 1 left, 2 back,
// 3 right. Motion codes (SPEC section 4): 0 forward, 2 turn left, 3 turn right.
module reflex_spec (
    input  wire [7:0] x,
    input  wire       enable,
    output wire       active,   // the reflex decides the motion
    output reg  [2:0] motion
);
    assign active = enable && (x[5:0] == 6'b0);
    always @* begin
        case (x[7:6])
            2'd0: motion = 3'd0;  // front: forward
            2'd1: motion = 3'd2;  // left: turn left
            2'd2: motion = 3'd2;  // back: turn left
            2'd3: motion = 3'd3;  // right: turn right
        endcase
    end
endmodule
