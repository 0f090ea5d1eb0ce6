"""The robot world: pymunk arena, sensors, motions, 64 relocation poses, noise and faults.

Public API: :mod:`sim_world.arena` (``load_arena``, ``Arena``, ``ARENAS``), :mod:`sim_world.world`
(``World``, ``Noise``, ``Fault``, ``Step``, ``DEFAULT_NOISE``), :mod:`sim_world.course`
(``run_course``, ``CourseResult``, ``DEFAULT_MAX_LEG_STEPS``), :mod:`sim_world.gym_env`
(``EHWTrackingEnv``, registered as the Gymnasium id ``EHWTracking-v0``). See docs/world.md.
"""

GYM_ID = "EHWTracking-v0"


def _register() -> None:
    # Registering needs only gymnasium's registry (the environment module is imported by make()),
    # so `gymnasium.make("sim_world:EHWTracking-v0")` works after this package is imported.
    try:
        import gymnasium
    except ImportError:  # pragma: no cover - gymnasium is a dependency; stay importable without it
        return
    if GYM_ID not in gymnasium.registry:
        gymnasium.register(id=GYM_ID, entry_point="sim_world.gym_env:EHWTrackingEnv")


_register()
