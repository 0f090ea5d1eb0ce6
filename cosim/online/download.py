"""Which controller of the evolved population goes to the robot (SPEC section 7, learning phase).

The paper downloads the best individual. After a time-out or a loop the world model does not hold
the loop (the robot came back to a state through noise the model cannot see), so the fittest
individual usually still chooses the motion that looped; the *escape* downloads instead the
fittest individual whose motion in the blamed state differs (docs/research-log.md, on-line round 1).
"""

from __future__ import annotations

import numpy as np

from ga.truth_table import truth_tables


def choose_download(population: np.ndarray, fitness: np.ndarray, blamed: tuple[int, int] | None = None,
                    reflex: bool = True) -> tuple[int, bool]:
    """(index of the individual to download, whether the escape changed it).

    ``blamed`` = None: the fittest (the first of ties). ``blamed`` = (state, motion): the fittest
    of the individuals that choose another motion in ``state`` (the fittest of all when none does
    or when it already does).
    """
    best = int(np.argmax(fitness))
    if blamed is None:
        return best, False
    state, motion = blamed
    differs = truth_tables(population, reflex=reflex)[:, state] != motion
    if not differs.any() or differs[best]:
        return best, False
    return int(np.flatnonzero(differs)[np.argmax(fitness[differs])]), True
