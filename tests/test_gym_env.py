"""The Gymnasium environment: spaces, check_env, registration, reproducible reset, rendering."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from sim_world.gym_env import CRASH_REWARD, TARGET_REWARD, EHWTrackingEnv
from sim_world.world import DEFAULT_NOISE


def test_check_env():
    env = EHWTrackingEnv(noise=DEFAULT_NOISE, render_mode="rgb_array")
    check_env(env)  # includes the render check (an rgb_array frame)
    env.close()


@pytest.mark.parametrize("env_id", ["EHWTracking-v0", "sim_world:EHWTracking-v0"])
def test_registered(env_id):
    import sim_world  # noqa: F401  (registers the id; the module prefix also imports it)

    env = gymnasium.make(env_id)
    assert env.action_space == gymnasium.spaces.Discrete(8)
    assert env.observation_space == gymnasium.spaces.Discrete(256)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.close()


def _episode(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, term, trunc, info["pose"]))
        if term or trunc:
            break
    return out


def test_reset_seed_reproducible():
    env = EHWTrackingEnv(noise=DEFAULT_NOISE)
    actions = np.random.default_rng(0).integers(0, 8, 300).tolist()
    assert _episode(env, 5, actions) == _episode(env, 5, actions)
    assert _episode(env, 5, actions) != _episode(env, 6, actions)


def test_rewards_and_termination():
    env = EHWTrackingEnv(arena="empty", max_leg_steps=20)
    env.reset(seed=0)
    env.world.place((2000.0, 1760.0, np.pi / 2))
    obs, r, term, trunc, info = env.step(0)  # forward into the target radius
    assert r == pytest.approx(TARGET_REWARD - 0.01) and info["targets"] == 1 and not term
    env.world.place((160.0, 2000.0, np.pi))
    obs, r, term, trunc, info = env.step(0)  # into the left wall
    assert r == pytest.approx(CRASH_REWARD - 0.01) and term
    env.reset(seed=0)
    for _ in range(19):
        assert not env.step(2)[3]
    assert env.step(2)[3]  # the 20th step of the leg truncates


def test_render_rgb_array():
    env = EHWTrackingEnv(render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert EHWTrackingEnv().render() is None
