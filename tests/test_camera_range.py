"""Honest sensing (SPEC section 4, issue 36): the camera's range estimate, and that the on-line
loop and the shaped peers learn from it, never from the simulator's exact distance."""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest

from cosim.online.config import OnlineConfig
from cosim.online.run import make_run
from ga.motions import N_MOTIONS
from sim_world.world import CAMERA_RANGE_SD, CAMERA_RANGE_STEP_MM, DEFAULT_NOISE, World, camera_range


def test_camera_range_scales_the_true_range_and_quantises_to_10_mm():
    assert CAMERA_RANGE_STEP_MM == 10.0 and DEFAULT_NOISE.range_sd == CAMERA_RANGE_SD == 0.10
    assert camera_range(1234.0) == 1230.0
    assert camera_range(1236.0) == 1240.0
    assert camera_range(1000.0, 0.1, 1.0) == 1100.0  # e = 0.1 x 1
    assert camera_range(1000.0, 0.1, -2.5) == 750.0
    assert camera_range(100.0, 0.5, -3.0) == 0.0  # never negative


def _drive(world: World, motions) -> list:
    world.reset_to_start()
    return [world.step(int(a)) for a in motions]


def test_range_readings_are_seeded_noisy_and_leave_the_other_noise_alone():
    motions = np.random.default_rng(7).integers(N_MOTIONS, size=3000)
    noisy = _drive(World("default", noise=DEFAULT_NOISE, seed=11), motions)
    again = _drive(World("default", noise=DEFAULT_NOISE, seed=11), motions)
    exact = _drive(World("default", noise=dataclasses.replace(DEFAULT_NOISE, range_sd=0.0), seed=11), motions)
    assert [s.range_mm for s in noisy] == [s.range_mm for s in again]  # seeded
    # the camera's own stream: the same poses, states, crashes and exact distances without it
    assert [s[:4] for s in noisy] == [s[:4] for s in exact]
    assert all(s.range_mm == camera_range(s.distance_mm) for s in exact)
    ranges = np.array([s.range_mm for s in noisy])
    true = np.array([s.distance_mm for s in noisy])
    assert np.all(ranges % CAMERA_RANGE_STEP_MM == 0)
    e = ranges / true - 1.0
    assert abs(e.mean()) < 0.01 and 0.09 < e.std() < 0.11  # N(0, 0.10), quantisation aside
    other = _drive(World("default", noise=DEFAULT_NOISE, seed=12), motions)
    assert [s.range_mm for s in other] != [s.range_mm for s in noisy]


def test_the_reading_holds_until_the_robot_is_sensed_again():
    world = World("default", noise=DEFAULT_NOISE, seed=3)
    step = world.step(0)
    assert world.camera_range() == step.range_mm == world.camera_range()
    start = world.relocate(5)
    assert start == world.state() and world.camera_range() % CAMERA_RANGE_STEP_MM == 0


SHORT = OnlineConfig(seed=1, n_targets=8)


def _lifetime(config: OnlineConfig) -> tuple[str, dict]:
    run = make_run(config, "reference", None).run()
    summary = run.summary()
    return hashlib.sha256(bytes(run.motions)).hexdigest(), summary


def test_raising_the_range_noise_changes_the_lifetime():
    base, summary = _lifetime(SHORT)
    raised, _ = _lifetime(dataclasses.replace(SHORT, range_noise=0.3))
    assert raised != base
    assert summary["learnt_from"]["progress"] == "camera range"
    assert summary["learnt_from"]["range_sd"] == CAMERA_RANGE_SD


def test_garbage_in_the_exact_distance_does_not_change_the_lifetime(monkeypatch):
    base, summary = _lifetime(SHORT)
    garbage = np.random.default_rng(0)
    step = World.step

    def garbage_step(self, motion):
        return step(self, motion)._replace(distance_mm=float(garbage.uniform(0, 5000)))

    monkeypatch.setattr(World, "step", garbage_step)
    monkeypatch.setattr(World, "target_distance", lambda self: float(garbage.uniform(0, 5000)))
    spoiled, spoiled_summary = _lifetime(SHORT)
    assert spoiled == base
    assert spoiled_summary["interactions"] == summary["interactions"]
    assert spoiled_summary["phases"] == summary["phases"]


def test_the_shaped_peers_learn_from_the_range_too(monkeypatch):
    from peers.lifetime import run_lifetime

    def lifetime() -> dict:
        return {k: v for k, v in run_lifetime("q-learning", 1, n_targets=4).items() if k != "cpu_s"}

    base = lifetime()
    garbage = np.random.default_rng(0)
    step = World.step

    def garbage_step(self, motion):
        return step(self, motion)._replace(distance_mm=float(garbage.uniform(0, 5000)))

    monkeypatch.setattr(World, "step", garbage_step)
    monkeypatch.setattr(World, "target_distance", lambda self: float(garbage.uniform(0, 5000)))
    assert lifetime() == base


def test_the_gym_env_rewards_progress_by_the_range():
    from sim_world.gym_env import PROGRESS_SCALE, STEP_COST, EHWTrackingEnv

    env = EHWTrackingEnv(noise=DEFAULT_NOISE, crash_ends=False)
    _, info = env.reset(seed=4)
    for a in [0, 0, 4, 2, 0, 5, 0, 0]:
        before = info["range_mm"]
        _, reward, _, _, info = env.step(a)
        if info["targets"] == 0 and reward > -1:
            assert reward == pytest.approx(PROGRESS_SCALE * (before - info["range_mm"]) / 1000 - STEP_COST)
