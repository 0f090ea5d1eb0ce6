"""Which controller of the evolved population goes to the robot (SPEC section 7, learning phase).

The paper downloads the best individual. After a time-out or a loop the world model does not hold
the loop (the robot came back to a state through noise the model cannot see), so the fittest
individual usually still chooses the motion that looped; the *escape* downloads instead the
fittest individual whose motion in the blamed state differs (docs/online.md, round 1).

The *loop memory* (round 6) remembers, for the current leg, every loop a stop ended, as the
obstacle (state, motion) pairs the controller ran in it; at every download of that leg (after a
crash too) an individual that would run one of them again gives way to the fittest that would
not. The GA, the model and the fitness are untouched; only the choice among the evolved
individuals changes.
"""

from __future__ import annotations

import numpy as np

from ga.truth_table import truth_tables


def choose_download(population: np.ndarray, fitness: np.ndarray, blamed: tuple[int, int] | None = None,
                    reflex: bool = True, loops=()) -> tuple[int, bool, bool]:
    """(index of the individual to download, whether the escape changed it, whether the loop
    memory changed it).

    ``blamed`` = None: the fittest (the first of ties). ``blamed`` = (state, motion): the fittest
    of the individuals that choose another motion in ``state`` (the fittest of all when none does
    or when it already does).

    ``loops``: the loops met on this leg (``cosim.failures.last_cycle``: the obstacle (state,
    motion) pairs of each). If the individual chosen above would run more of them again (choose
    every motion of a loop) than some other individual, the fittest of those that run the fewest
    is downloaded instead (docs/online.md, round 6).
    """
    tables = None
    choice, escaped = int(np.argmax(fitness)), False
    if blamed is not None:
        state, motion = blamed
        tables = truth_tables(population, reflex=reflex)
        differs = tables[:, state] != motion
        if differs.any() and not differs[choice]:
            choice, escaped = int(np.flatnonzero(differs)[np.argmax(fitness[differs])]), True
    if not loops:
        return choice, escaped, False
    if tables is None:
        tables = truth_tables(population, reflex=reflex)
    again = np.zeros(len(population), dtype=np.int64)
    for loop in loops:
        states = np.array([s for s, _ in loop], dtype=np.int64)
        motions = np.array([a for _, a in loop], dtype=tables.dtype)
        again += (tables[:, states] == motions).all(axis=1)
    if again[choice] == again.min():
        return choice, escaped, False
    fewest = np.flatnonzero(again == again.min())
    return int(fewest[np.argmax(fitness[fewest])]), escaped, True
