"""The ``ehw`` command line: ``main`` (the subcommands and the console script), ``commands``
(``ehw sim`` and ``ehw offline``: run folders, sessions, printing), ``online`` (the on-line
experiment's options) and ``options`` (the HDL settings from options or the environment).
The top floor: imports everything below it, nothing imports it.
"""
