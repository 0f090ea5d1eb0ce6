"""The off-line model-free method (paper section 5.1): evolution in the simulator.

``run`` (the noise-free evolution to 64 targets, checkpointed), ``noisy`` (the noisy stage after
it), ``report`` (the paper's Fig. 5 and 6, the table over seeds). Imports ``ga``, ``sim_world``,
``base`` and ``cosim.paper``.
"""
