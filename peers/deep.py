"""DQN and PPO (stable-baselines3) on the Gymnasium env, one lifetime under the paper's protocol.

Needs the optional extra: ``pip install -e '.[rl]'`` (stable-baselines3 and the CPU build of
torch). The learner drives ``sim_world.gym_env.EHWTrackingEnv`` through :func:`lifetime_env`:

* the noisy world (``DEFAULT_NOISE``), the same arena and relocation course (the env's own);
  every reset of the env is seeded with the run's world seed (``peers.lifetime.seeds``), and the
  learner (network initialisation, exploration, minibatches) with an integer drawn from the
  run's learner generator;
* one continuing lifetime: a crash does not end the episode (``crash_ends=False``), no leg
  time-out (``max_leg_steps`` above the cap); the episode ends at 64 targets, the lifetime at 64
  targets or at the cap (``max_interactions``, 100,000);
* the reflex (:class:`Reflex`): in the four obstacle-free states the reflex motion is executed
  whatever the agent chose (the transition is stored with the agent's action; every action there
  has the same outcome, so the learner learns they are equal);
* every environment step is one interaction (``model.num_timesteps``), exploration and the
  steps before learning starts included.

Rewards: ``shaped`` is the env's reward (target +10, crash -5, step -0.01, plus the progress
towards the ball: the shaping, measured by the camera's noisy range estimate, SPEC section 4);
``unshaped`` (:class:`Unshaped`) removes the progress term, computed from the range the env
reports in ``info["range_mm"]``.

Hyper-parameters: stable-baselines3's defaults except those in ``HYPER`` (scaled to a lifetime of
at most 100,000 steps: DQN's exploration schedule and target updates run on the default's 1M-step
scale otherwise; set by hand), and over those the values ``TUNED`` holds per (learner, reward):
shaped, chosen by ``ehw tune`` on the tuning seeds (``peers.tabular.TUNING_SEEDS``) only; unshaped,
the earlier grid's learning rate on seeds 1001-1003.
"""

from __future__ import annotations

import time

import gymnasium as gym

from ga.motions import REFLEX_TABLE
from peers.lifetime import MAX_INTERACTIONS, SHAPINGS, seeds
from sim_world.arena import N_POSITIONS
from sim_world.gym_env import PROGRESS_SCALE, EHWTrackingEnv
from sim_world.world import DEFAULT_NOISE

HYPER = {
    "dqn": {"learning_starts": 500, "exploration_fraction": 0.05, "exploration_final_eps": 0.02,
            "target_update_interval": 500, "train_freq": 4, "gamma": 0.95, "learning_rate": 5e-4},
    "ppo": {"n_steps": 512, "batch_size": 64, "n_epochs": 4, "gamma": 0.95, "ent_coef": 0.01},
}

# (learner, reward) -> the values over HYPER. Shaped: the best trial of `ehw tune METHOD --trials 20`
# on the tuning seeds (peers.tabular.TUNING_SEEDS, 1001-1005; TPE seed 0; results/tune/<method>-shaped.json;
# docs/peers.md). Unshaped: not in that study (a deep unshaped lifetime is 20-40 CPU s, PPO's reach
# the cap); the earlier grid's choice on seeds 1001-1003 (docs/research-log.md, "Peers").
TUNED: dict[tuple[str, str], dict] = {
    # median 15,639 (trial 19; the earlier settings: 21,603)
    ("dqn", "shaped"): {"learning_rate": 0.001523499581977857, "gamma": 0.8254843054657862, "exploration_fraction": 0.1507416933410105, "exploration_final_eps": 0.004522592873756487},
    # median 10,548 (trial 15; the earlier settings: 14,408)
    ("ppo", "shaped"): {"learning_rate": 0.00288948675424056, "gamma": 0.9184808180841996, "ent_coef": 0.0010599083177377235},
    ("dqn", "unshaped"): {"learning_rate": 0.001, "exploration_fraction": 0.05},  # grid median 39,464
    # every PPO unshaped grid point was capped at 100,000 on all three seeds (a tie: the first point)
    ("ppo", "unshaped"): {"learning_rate": 0.0003},  # grid median 100,000 (capped)
}


def tuned_hyper(method: str, shaping: str = "shaped") -> dict:
    if method not in HYPER:
        raise ValueError(f"deep learner must be one of {sorted(HYPER)}, got {method!r}")
    if shaping not in SHAPINGS:
        raise ValueError(f"shaping must be one of {SHAPINGS}, got {shaping!r}")
    return {**HYPER[method], **TUNED.get((method, shaping), {})}


class Reflex(gym.ActionWrapper):
    """In a reflex state (no obstacle bit) the reflex motion replaces the agent's action."""

    def __init__(self, env):
        super().__init__(env)
        self._obs = 0

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._obs = int(obs)
        return obs, info

    def action(self, action):
        forced = int(REFLEX_TABLE[self._obs])
        return forced if forced >= 0 else int(action)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        self._obs = int(obs)
        return obs, reward, terminated, truncated, info


class Unshaped(gym.Wrapper):
    """The env's reward less its progress term: target, crash and step rewards only."""

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._range, self._targets = info["range_mm"], info["targets"]
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info["targets"] == self._targets and not info["crashed"]:  # the progress term was added
            reward -= PROGRESS_SCALE * (self._range - info["range_mm"]) / 1000.0
        self._range, self._targets = info["range_mm"], info["targets"]
        return obs, float(reward), terminated, truncated, info


class Lifetime(gym.Wrapper):
    """Resets seed the env with the run's world seed; counts interactions, crashes and targets."""

    def __init__(self, env, world_seed: int):
        super().__init__(env)
        self.world_seed = int(world_seed)
        self.crashes = 0
        self.target_interactions: list[int] = []
        self.steps = 0

    def reset(self, *, seed=None, options=None):
        """Reset with ``seed`` if given (as Gymnasium's checker asks), else the run's world seed."""
        return self.env.reset(seed=self.world_seed if seed is None else seed, options=options)

    def step(self, action):
        before = getattr(self, "_targets", 0)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        if info["targets"] > before:
            self.target_interactions.append(self.steps)
        elif info["crashed"]:  # (not by the reward: a noisy range's progress term can be as low)
            self.crashes += 1
        self._targets = info["targets"]
        return obs, reward, terminated, truncated, info


def lifetime_env(seed: int, shaping: str = "shaped", arena: str = "default",
                 max_interactions: int = MAX_INTERACTIONS, n_targets: int = N_POSITIONS) -> Lifetime:
    if shaping not in SHAPINGS:
        raise ValueError(f"shaping must be one of {SHAPINGS}, got {shaping!r}")
    world_seed, _ = seeds(seed)
    env = EHWTrackingEnv(arena, noise=DEFAULT_NOISE, max_leg_steps=max_interactions + 1, n_targets=n_targets,
                         crash_ends=False)
    env = Reflex(env)
    if shaping == "unshaped":
        env = Unshaped(env)
    return Lifetime(env, world_seed)


def run_deep_lifetime(method: str, seed: int, *, shaping: str = "shaped", hyper: dict | None = None,
                      arena: str = "default", max_interactions: int = MAX_INTERACTIONS,
                      n_targets: int = N_POSITIONS) -> dict:
    """One lifetime of stable-baselines3's DQN or PPO; the figures as ``peers.lifetime`` gives them."""
    import torch
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.callbacks import BaseCallback

    cpu0 = time.process_time()
    torch.set_num_threads(1)  # one core per lifetime, as every other method
    hyper = tuned_hyper(method, shaping) if hyper is None else dict(hyper)
    _, rng = seeds(seed)
    env = lifetime_env(seed, shaping, arena, max_interactions, n_targets)

    class StopAt64(BaseCallback):
        def _on_step(self) -> bool:
            return len(env.target_interactions) < n_targets and self.num_timesteps < max_interactions

    algo = {"dqn": DQN, "ppo": PPO}[method]
    model = algo("MlpPolicy", env, seed=int(rng.integers(2**31 - 1)), device="cpu", verbose=0, **hyper)
    model.get_env().seed(env.world_seed)  # learn()'s first reset: the world seed, not the learner's
    model.learn(total_timesteps=max_interactions, callback=StopAt64())
    interactions = env.steps
    return {
        "method": f"{method}/{shaping}",
        "seed": int(seed),
        "interactions": interactions,
        "targets_reached": len(env.target_interactions),
        "crashes": env.crashes,
        "target_interactions": env.target_interactions,
        "config": {"hyper": hyper, "shaping": shaping, "arena": arena, "max_interactions": max_interactions},
        "generations": None,
        "genetic_operations": None,
        "cpu_s": round(time.process_time() - cpu0, 3),
    }
