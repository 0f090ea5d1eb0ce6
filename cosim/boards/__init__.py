"""The EHW boards as the experiment loops see them (SPEC sections 9 and 12).

``interfaces`` (the protocols), ``reference`` (the NumPy backend), ``registry`` (every backend by
name: the loops call ``make_boards`` and never import a backend), the HDL backends
(``amaranth_backend``, ``amaranth_learning``, ``cocotb_backend``, ``cocotb_learning``),
``cocotb_run`` (building Verilog and running a cocotb test from Python) and ``hardware_time``
(clock cycles at the FPGA clock). Imports ``base``, ``ga``, ``hdl`` only; ``cosim.link`` and
``cosim.launch`` are named in the registry by string, never imported.
"""
