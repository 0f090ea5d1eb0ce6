"""A Gymnasium environment around the robot world, so any RL library can drive it.

``gymnasium.make("EHWTracking-v0")`` after ``import sim_world``, or
``gymnasium.make("sim_world:EHWTracking-v0")`` without importing anything first.

* Action: ``Discrete(8)``, the motion code of SPEC section 4 (``ga.motions.Motion``).
* Observation: ``Discrete(256)``, the 8-bit world state x0..x7 (SPEC section 4) as an integer.
  A discrete state is what the EHW controller sees, what the world model is indexed by, and what
  a tabular learner needs; ``info["pose"]`` carries the hidden pose for analysis only.
* An episode is the course: the robot starts at the start pose; each time it reaches the target
  it is relocated to the next of the 64 positions. ``terminated`` when ``n_targets`` targets are
  reached or, with ``crash_ends=True`` (the default, as in the off-line method), at a crash;
  ``truncated`` when one leg exceeds ``max_leg_steps`` interactions.
* Reward per step: ``TARGET_REWARD`` (+10) on reaching the target; ``CRASH_REWARD`` (-5) on a
  crash; otherwise the progress towards the ball in metres x ``PROGRESS_SCALE`` (10, so a
  5 cm step straight at the ball earns +0.5), minus ``STEP_COST`` (0.01) for every interaction.
  The progress is measured by the camera's range estimate (SPEC section 4, ``info["range_mm"]``:
  noisy when the world's ``Noise.range_sd`` is set), never the exact distance
  (``info["distance_mm"]``, like ``info["pose"]``, is for analysis only).
* ``reset(seed=...)`` seeds the world's noise generator: the same seed and actions give the same
  episode. ``render_mode="rgb_array"`` draws the arena, the robot and its IR rays (matplotlib,
  imported lazily).
* Gymnasium's conventions: ``step`` before the first ``reset`` raises ``ResetNeeded``; a step
  after ``terminated`` or ``truncated`` warns once (as Gymnasium's own environments do) and
  changes nothing (no motion, reward 0, the same flags) until ``reset``; an action must be an
  integer motion code (``True`` is not one); ``reset(options=...)`` takes ``None`` or an empty
  dict and rejects any key (it has no options).
* The reflex (SPEC section 6) is not applied: the agent chooses every motion. Wrap the action with
  ``ga.motions.REFLEX_TABLE`` to learn under the reflex.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import logger, spaces
from gymnasium.error import ResetNeeded

from ga.motions import N_MOTIONS, N_STATES
from sim_world.arena import N_POSITIONS, Arena, load_arena
from sim_world.course import DEFAULT_MAX_LEG_STEPS, Course
from sim_world.world import Noise, World

TARGET_REWARD = 10.0
CRASH_REWARD = -5.0
PROGRESS_SCALE = 10.0  # reward per metre of progress towards the ball
STEP_COST = 0.01


class EHWTrackingEnv(gym.Env):
    """The tracking task of Keymeulen et al. 1998 as a Gymnasium environment (see module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        arena: Arena | str = "default",
        noise: Noise | None = None,
        faults=(),
        max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
        n_targets: int = N_POSITIONS,
        crash_ends: bool = True,
        render_mode: str | None = None,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.arena = load_arena(arena) if isinstance(arena, str) else arena
        self.world = World(self.arena, noise=noise, faults=faults)
        self.max_leg_steps = int(max_leg_steps)
        self.n_targets = int(n_targets)
        self.crash_ends = crash_ends
        self.render_mode = render_mode
        self.action_space = spaces.Discrete(N_MOTIONS)
        self.observation_space = spaces.Discrete(N_STATES)
        self._targets = 0
        self._leg_steps = 0
        self._needs_reset = True  # before the first reset
        self._ended: tuple | None = None  # (obs, terminated, truncated) once the episode ended
        self._warned_after_end = False

    def _info(self, crashed: bool = False) -> dict:
        return {
            "crashed": crashed,  # the bumper hit something in this step (the pose was restored)
            "pose": self.world.pose,
            "targets": self._targets,
            "leg_steps": self._leg_steps,
            "interactions": self.world.interactions,
            "distance_mm": self.world.target_distance(),  # exact: analysis only
            "range_mm": self.world.camera_range(),  # what the robot senses of it
        }

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"options must be a dict or None, got {type(options).__name__} {options!r}")
        if options:
            raise ValueError(f"EHWTrackingEnv.reset takes no options, got {sorted(options)!r}")
        super().reset(seed=seed)
        # The world's noise generator is seeded from the environment's own generator.
        self.world.reset(int(self.np_random.integers(2**63 - 1)))
        state = self.world.reset_to_start()
        self._targets = 0
        self._leg_steps = 0
        self._needs_reset = False
        self._ended = None
        self._warned_after_end = False
        return int(state), self._info()

    def step(self, action):
        if isinstance(action, (bool, np.bool_)) or not self.action_space.contains(action):
            raise ValueError(f"action must be a motion code 0..{N_MOTIONS - 1} (an integer), got {action!r}")
        if self._needs_reset:
            raise ResetNeeded("call reset() before step()")
        if self._ended is not None:
            if not self._warned_after_end:
                logger.warn("You are calling 'step()' even though this environment has already returned "
                            "terminated = True or truncated = True. You should always call 'reset()' "
                            "once you receive it; this step does nothing.")
                self._warned_after_end = True
            obs, terminated, truncated = self._ended
            return obs, 0.0, terminated, truncated, self._info()
        before = self.world.camera_range()
        out = self.world.step(int(action))
        self._leg_steps += 1
        terminated = truncated = False
        if out.crashed:
            reward = CRASH_REWARD
            terminated = self.crash_ends
        elif out.reached:
            reward = TARGET_REWARD
            self._targets += 1
            self._leg_steps = 0
            if self._targets >= self.n_targets:
                terminated = True
            else:
                Course.of(self.arena).relocate(self.world, self._targets)
        else:
            reward = PROGRESS_SCALE * (before - out.range_mm) / 1000.0
        reward -= STEP_COST
        if not terminated and self._leg_steps >= self.max_leg_steps:
            truncated = True
        obs = int(self.world.state())
        if terminated or truncated:
            self._ended = (obs, terminated, truncated)
        return obs, float(reward), terminated, truncated, self._info(out.crashed)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from sim_world.render import _plt, draw_arena, draw_robot

        plt = _plt()
        fig, ax = plt.subplots(figsize=(4, 4), dpi=80)
        draw_arena(ax, self.arena, numbers=False)
        draw_robot(ax, self.world)
        ax.set_title(f"targets {self._targets}, state {self.world.state():08b}", fontsize=8)
        fig.canvas.draw()
        image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
        plt.close(fig)
        return image
