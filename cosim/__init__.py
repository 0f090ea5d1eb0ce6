"""The experiments around the EHW boards: the on-line and off-line methods, the comparison, the
board backends and the host link, and the ``ehw`` command line.

Floors, top to bottom (a module imports only from its own floor's package or the floors below;
``base``, ``ga``, ``sim_world``, ``hdl`` and ``peers`` lie under all of them):

- ``cosim.cli``: the ``ehw`` command line (parsers, run folders, printing);
- ``cosim.launch`` and ``cosim.compare``: a lifetime inside a simulator; every method over N seeds;
- ``cosim.online``, ``cosim.offline`` and ``cosim.link``: the two methods; the host side of the
  UART link;
- ``cosim.boards``: the board interfaces, the reference backend and the HDL backends (by name);
- ``cosim.paper``: the paper's figures.
"""
