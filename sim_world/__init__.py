"""The robot world: pymunk arena, sensors, motions, 64 relocation poses, noise and faults.

Public API: :mod:`sim_world.arena` (``load_arena``, ``Arena``, ``ARENAS``), :mod:`sim_world.world`
(``World``, ``Noise``, ``Fault``, ``Step``, ``DEFAULT_NOISE``), :mod:`sim_world.course`
(``run_course``, ``CourseResult``, ``DEFAULT_MAX_LEG_STEPS``). See docs/world.md.
"""
