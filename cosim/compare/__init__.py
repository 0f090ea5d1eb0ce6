"""Every method on the same robot, arena and course over N seeds: the comparison table.

``run`` (the tasks and their runners: on-line, off-line, baseline, the RL peers), ``options``
(its options, checked before any work), ``report`` (statistics, ``compare.md`` and the plot) and
``sweep`` (one executor for many lifetimes: processes or a Dask cluster, with a cache). Imports
``cosim.online``, ``cosim.offline``, ``peers`` and below.
"""
