"""peers: the tabular learners on a maze with a known optimum, their robot lifetime under the
on-line protocol, and the deep-RL lifetime (skipped without the optional extra [rl])."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from ga.motions import N_STATES, REFLEX_STATES, REFLEX_TABLE
from peers import maze
from peers.lifetime import allowed_actions, run_lifetime, seeds
from peers.tabular import LEARNERS, LearnerConfig, make_learner

# Optimistic start (q_init = the goal reward) explores systematically; the same for all three.
MAZE = dict(alpha=0.5, gamma=0.95, epsilon=0.1, q_init=1.0)


def _maze_steps(method: str, seed: int) -> int | None:
    cfg = LearnerConfig(**MAZE, planning_steps=0 if method == "q-learning" else 20)
    if method == "dyna-q+":  # it explores by its bonus, not by optimism
        cfg = dataclasses.replace(cfg, q_init=0.0, kappa=1e-4)
    learner = make_learner(method, maze.ALLOWED, cfg, np.random.default_rng(seed))
    return maze.learn_maze(learner, max_episodes=300)["real_steps"]


def test_maze_has_the_known_shortest_path():
    assert maze.shortest_path() == 14  # S&B Figure 8.2
    # the path below the walls, written out by hand: down 2, right 4, up 1, right 4, up 3
    d, r, u = 1, 2, 0
    policy = [u] * maze.N_STATES
    for cell, a in {(2, 0): d, (3, 0): d, (4, 0): r, (4, 1): r, (4, 2): r, (4, 3): r, (4, 4): u,
                    (3, 4): r, (3, 5): r, (3, 6): r, (3, 7): r, (3, 8): u, (2, 8): u, (1, 8): u}.items():
        policy[maze.index(cell)] = a
    assert maze.greedy_path(policy) == 14
    assert maze.greedy_path([r] * maze.N_STATES) is None  # into the wall at (2, 2): never there


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_learner_finds_the_shortest_path_and_planning_needs_fewer_real_steps(seed):
    steps = {m: _maze_steps(m, seed) for m in LEARNERS}
    assert all(v is not None for v in steps.values()), steps
    # as in Kaelbling, Littman and Moore (1996, Table 1): Q-learning > Dyna > prioritized sweeping
    assert steps["dyna-q"] < steps["q-learning"] / 2, steps
    assert steps["dyna-q+"] < steps["q-learning"] / 2, steps
    assert steps["prioritized-sweeping"] < steps["q-learning"] / 2, steps


def test_learners_are_seeded_from_their_generator_only():
    def run(seed):
        learner = make_learner("dyna-q", maze.ALLOWED, LearnerConfig(**MAZE, planning_steps=5),
                               np.random.default_rng(seed))
        maze.learn_maze(learner, max_episodes=3)
        return learner.q

    assert run(4) == run(4)
    assert run(4) != run(5)
    with pytest.raises(TypeError, match="Generator"):
        make_learner("q-learning", maze.ALLOWED, LearnerConfig(), 4)
    with pytest.raises(ValueError, match="alpha"):
        LearnerConfig(alpha=0.0)


def test_dyna_q_plus_models_untried_actions_and_plans_with_the_bonus():
    allowed = [[0, 1, 2], [0, 1, 2]]
    cfg = LearnerConfig(alpha=0.5, gamma=0.9, epsilon=0.0, planning_steps=50, kappa=0.1)
    learner = make_learner("dyna-q+", allowed, cfg, np.random.default_rng(0))
    learner.observe(0, 0, 0.0, 1)
    # the untried actions of state 0 stay put with reward 0; state 1 is not visited yet
    assert learner.model == {(0, 0): (0.0, 1, False), (0, 1): (0.0, 0, False), (0, 2): (0.0, 0, False)}
    for _ in range(20):
        learner.observe(0, 0, 0.0, 1)
    # every reward is 0: only the bonus kappa sqrt(tau) makes a value, largest for the untried ones
    assert learner.q[0][1] > 0 and learner.q[0][2] > 0
    assert min(learner.q[0][1], learner.q[0][2]) > learner.q[0][0]
    plain = make_learner("dyna-q+", allowed, dataclasses.replace(cfg, kappa=0.0), np.random.default_rng(0))
    for _ in range(21):
        plain.observe(0, 0, 0.0, 1)
    assert plain.q == [[0.0] * 3, [0.0] * 3]
    with pytest.raises(ValueError, match="kappa"):
        LearnerConfig(kappa=-1.0)


def test_prioritized_sweeping_propagates_a_reward_backwards_in_one_step():
    # a chain 0 -> 1 -> 2 -> 3 (goal): once every link is in the model, one real step at the goal
    # sweeps the reward back to the start; Q-learning moves it one link per visit
    allowed = [[0]] * 5
    cfg = LearnerConfig(alpha=1.0, gamma=0.9, epsilon=0.0, planning_steps=10)
    ps = make_learner("prioritized-sweeping", allowed, cfg, np.random.default_rng(0))
    q = make_learner("q-learning", allowed, cfg, np.random.default_rng(0))
    for learner in (ps, q):
        for s in range(3):
            learner.observe(s, 0, 0.0, s + 1)
        learner.observe(3, 0, 1.0, 4, True)
    assert ps.q[0][0] == pytest.approx(0.9 ** 3)
    assert q.q[0][0] == 0.0 and q.q[3][0] == 1.0


def test_the_reflex_leaves_one_motion_in_the_obstacle_free_states():
    allowed = allowed_actions(reflex=True)
    assert len(allowed) == N_STATES
    for s in range(N_STATES):
        if s in REFLEX_STATES:
            assert allowed[s] == [int(REFLEX_TABLE[s])]
        else:
            assert allowed[s] == list(range(8))
    assert all(len(a) == 8 for a in allowed_actions(reflex=False))


def test_seeds_follow_the_online_scheme():
    from cosim.online.run import _seeds

    world_seed, rng = seeds(7)
    online_world, online_rng = _seeds(7)
    assert world_seed == online_world
    assert rng.integers(2**62) == online_rng.integers(2**62)


def test_lifetime_is_counted_capped_and_reproducible():
    a = run_lifetime("q-learning", 3, shaping="shaped", max_interactions=1500)
    b = run_lifetime("q-learning", 3, shaping="shaped", max_interactions=1500)
    a.pop("cpu_s"), b.pop("cpu_s")
    assert a == b
    assert a["interactions"] == 1500 and 0 < a["targets_reached"] < 64  # capped, some targets met
    assert a["target_interactions"] == sorted(a["target_interactions"])
    assert len(a["target_interactions"]) == a["targets_reached"]
    assert a["target_interactions"][-1] <= 1500
    c = run_lifetime("q-learning", 3, shaping="unshaped", max_interactions=1500)
    assert c["target_interactions"] != a["target_interactions"]  # the shaping changes what it learns
    with pytest.raises(ValueError, match="shaping"):
        run_lifetime("q-learning", 3, shaping="dense")


def test_lifetime_stops_at_the_targets():
    res = run_lifetime("prioritized-sweeping", 2, shaping="shaped", n_targets=3, max_interactions=20_000)
    assert res["targets_reached"] == 3
    assert res["interactions"] == res["target_interactions"][-1]


# -- deep RL (optional extra) -------------------------------------------------------------------

def _need_sb3():
    return pytest.importorskip("stable_baselines3", reason="the optional extra [rl] is not installed "
                               "(pip install -e '.[rl]')")


def test_lifetime_env_passes_both_checkers():
    _need_sb3()
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    from peers.deep import lifetime_env
    from sim_world.gym_env import EHWTrackingEnv

    sb3_check(EHWTrackingEnv(), warn=True)
    env = lifetime_env(1, "unshaped", max_interactions=500)  # every wrapper of a lifetime
    sb3_check(env, warn=True)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*different from the unwrapped")  # wrappers on purpose
        gym_check(env, skip_render_check=True)


def test_lifetime_env_applies_the_reflex_and_unshapes():
    from peers.deep import lifetime_env  # the wrappers need gymnasium only

    shaped, unshaped = lifetime_env(2, "shaped"), lifetime_env(2, "unshaped")
    obs_s, _ = shaped.reset()
    obs_u, _ = unshaped.reset()
    assert obs_s == obs_u
    rng = np.random.default_rng(0)
    crashes = 0
    for _ in range(2000):
        a = int(rng.integers(8))
        obs, r_s, *_ = shaped.step(a)
        before = unshaped.unwrapped.world.crashes
        obs2, r_u, _, _, info = unshaped.step(a)
        crashed = unshaped.unwrapped.world.crashes > before
        crashes += crashed
        assert obs == obs2  # same world, same noise: the reward alone differs
        assert info["crashed"] == crashed
        assert r_u == pytest.approx(-5.01 if crashed else -0.01) or r_u == pytest.approx(10 - 0.01)
    assert shaped.steps == 2000
    # crashes counted by the bumper, not by the reward (a noisy range's progress term can be -5 too)
    assert shaped.crashes == unshaped.crashes == crashes > 0


@pytest.mark.parametrize("method", ["dqn", "ppo"])
def test_deep_lifetime_counts_every_step(method):
    _need_sb3()
    from peers.deep import run_deep_lifetime

    res = run_deep_lifetime(method, 1, max_interactions=300)
    assert res["interactions"] == 300
    assert res["targets_reached"] == len(res["target_interactions"]) < 64
