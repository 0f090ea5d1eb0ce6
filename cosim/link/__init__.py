"""The host side of the UART link (``hdl.link_protocol``): the client and the boards behind it.

``host`` (frames, retries, the board commands), ``boards`` (the controller and evaluator boards
over the link, and the ``serial`` backend on a real port), ``learning`` (the learning board over
the link), ``simulated`` (the serial lines into a cocotb simulation: the ``uart`` backend's
boards). Imports ``cosim.boards`` and below.
"""
