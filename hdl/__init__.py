"""The Amaranth gateware: the AND-OR array, the controller and evaluator EHW boards, the learning
engine, the UART link and its board tops, the FPGA builds (``fpga``) and the Verilog generator.
Each block has its NumPy reference in ``ga``; imports ``ga`` and ``base`` only.
"""
