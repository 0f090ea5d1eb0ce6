"""A small deterministic maze with a known shortest path: the check that each learner learns.

The maze is the Dyna maze of Sutton and Barto (2018, Example 8.1, Figure 8.2): 6 rows x 9
columns, start S at row 2 column 0, goal G at row 0 column 8, seven wall cells; four moves
(up, down, right, left), a move into a wall or off the grid stays put. Reward 1 on entering G
(the episode ends, the agent starts again at S), 0 otherwise; so the greedy policy of a learner
that has converged takes the shortest path, 14 moves (by breadth-first search, ``shortest_path``).

:func:`learn_maze` runs a learner episode after episode and reports the real steps (moves made in
the maze; planning is free) until its greedy path from S is a shortest one. In S&B's Figure 8.2
Dyna-Q with 5-50 planning steps needs a few episodes where Q-learning needs tens: the model-based
learners should need fewer real steps, as in Kaelbling, Littman and Moore (1996, Table 1).
"""

from __future__ import annotations

from collections import deque

ROWS, COLS = 6, 9
START = (2, 0)
GOAL = (0, 8)
WALLS = frozenset({(1, 2), (2, 2), (3, 2), (4, 5), (0, 7), (1, 7), (2, 7)})
MOVES = ((-1, 0), (1, 0), (0, 1), (0, -1))  # up, down, right, left
N_STATES = ROWS * COLS
ALLOWED = [list(range(len(MOVES)))] * N_STATES


def index(cell: tuple[int, int]) -> int:
    return cell[0] * COLS + cell[1]


def step(s: int, a: int) -> tuple[int, float, bool]:
    """(next state, reward, done) of move ``a`` from state ``s``."""
    r, c = divmod(s, COLS)
    dr, dc = MOVES[a]
    cell = (r + dr, c + dc)
    if not (0 <= cell[0] < ROWS and 0 <= cell[1] < COLS) or cell in WALLS:
        cell = (r, c)
    s2 = index(cell)
    done = cell == GOAL
    return s2, (1.0 if done else 0.0), done


def shortest_path() -> int:
    """Moves from S to G on a shortest path (breadth-first search)."""
    start, goal = index(START), index(GOAL)
    dist = {start: 0}
    queue = deque([start])
    while queue:
        s = queue.popleft()
        for a in range(len(MOVES)):
            s2, _, _ = step(s, a)
            if s2 not in dist:
                dist[s2] = dist[s] + 1
                queue.append(s2)
    return dist[goal]


def greedy_path(policy: list[int]) -> int | None:
    """Moves from S to G following ``policy`` (None if it never gets there)."""
    s, seen = index(START), set()
    for n in range(1, N_STATES + 1):
        seen.add(s)
        s, _, done = step(s, policy[s])
        if done:
            return n
        if s in seen:
            return None
    return None


def learn_maze(learner, max_episodes: int = 200, max_episode_steps: int = 10_000) -> dict:
    """Episodes until the learner's greedy path is a shortest one: {"real_steps", "episodes",
    "path"}; real_steps is None if it did not get there within ``max_episodes``."""
    optimum = shortest_path()
    real = 0
    for episode in range(1, max_episodes + 1):
        s = index(START)
        for _ in range(max_episode_steps):
            a = learner.act(s)
            s2, r, done = step(s, a)
            learner.observe(s, a, r, s2, done)
            real += 1
            s = s2
            if done:
                break
        path = greedy_path(learner.policy())
        if path == optimum:
            return {"real_steps": real, "episodes": episode, "path": path}
    return {"real_steps": None, "episodes": max_episodes, "path": greedy_path(learner.policy())}
