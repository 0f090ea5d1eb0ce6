"""A lifetime inside a simulator: the backends whose boards exist only in a running cocotb test.

``lifetime`` (what both launchers share), ``cocotb_sim`` / ``cocotb_test`` (the ``cocotb``
backend: the launcher and the cocotb test module), ``uart_sim`` / ``uart_test`` (the ``uart``
backend: the link top with its UART in Verilator). A ``*_test`` module is imported only by
cocotb. Imports ``cosim.online``, ``cosim.link``, ``cosim.boards`` and below.
"""
