"""The formal proofs of the gateware (``make formal``, Yosys SAT): properties in ``*.sv``/``*.v``
beside the Amaranth blocks of ``hdl``; ``python -m formal`` is ``ehw formal``.
"""
