"""The on-line model-based method (paper section 5.2, SPEC section 7): one robot lifetime.

``run`` (the lifetime: execution and learning phases, checkpoints), ``config`` (every knob,
checked at once), ``failures`` (when a leg stops for learning), ``learning_phase`` (the GA on the
learning board, ``--ga hardware``), ``download`` (which controller goes to the robot) and
``report`` (summary, figures). Talks to the boards only through ``cosim.boards.registry``;
imports ``cosim.boards`` and below.
"""
