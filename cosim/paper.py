"""The paper's figures (Keymeulen et al. 1998, section 5), printed beside ours.

The single place for them: the on-line and off-line runners and ``make compare`` import these
dicts. Keys are the names our summaries use.
"""

from __future__ import annotations

from sim_world.arena import N_POSITIONS

# Section 5.2, on-line model-based: 12,280 interactions to the 64th target; 242,500 genetic
# operations at population 500 are 485 generations.
PAPER_ONLINE = {
    "interactions": 12_280,
    "generations": 485,
    "genetic_operations": 242_500,
    "world_states": 84,
    "transitions": 334,
    "targets_reached": N_POSITIONS,
}

# Section 5.1, off-line model-free: the best individual reached the target 64 times at
# generation 285 (population 20: 5,700 genetic operations).
PAPER_OFFLINE = {
    "interactions": 3_283_269,
    "generations": 285,
    "genetic_operations": 5_700,
    "world_states": 122,
    "transitions": 744,
    "targets_reached": N_POSITIONS,
}
