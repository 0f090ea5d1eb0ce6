"""Peers on the same task: reinforcement learners run under the paper's protocol (issue 16).

* :mod:`peers.tabular` -- Q-learning, Dyna-Q and prioritized sweeping on a table of Q-values,
  generic over a finite MDP (any number of states, a set of allowed actions per state).
* :mod:`peers.lifetime` -- one robot lifetime of such a learner in the noisy world: the same
  arena, relocation course, reflex, seeds and interaction count as the on-line method.
* :mod:`peers.maze` -- a small deterministic grid maze with a known shortest path, where each
  learner is checked to find it (and the model-based ones to need fewer real steps).
* :mod:`peers.deep` -- DQN and PPO of stable-baselines3 on the Gymnasium env (optional extra
  ``[rl]``; imported only when those methods are asked for).
"""
