"""The genetic algorithm and the contracts it owns: the genome layout (``genome``), the motion
table (``motions``), truth tables, the world model, the evaluator and its fitness, the operators,
the hardware GA and the learnt per-pair codes (``fail_rates``). Imports only ``base``.
"""
