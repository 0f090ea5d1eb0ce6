"""Pictures of an arena and of a run, in the style of the paper's Fig. 5 and Fig. 9.

``python -m sim_world.render --out results`` writes results/arena_<name>.png for the shipped arenas
(obstacles, ball, start, the 64 numbered relocation poses, the robot's IR rays at the start pose).
:func:`plot_trajectory` is what the experiments call to draw a run. matplotlib is imported lazily
(Agg backend), so importing sim_world never pulls it in.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from base.files import atomic_savefig
from sim_world.arena import ARENAS, ROBOT_RADIUS_MM, Arena, load_arena


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_arena(ax, arena: Arena, numbers: bool = True, target_zone: bool = True) -> None:
    """Draw border, obstacles, ball, start and (optionally numbered) relocation poses on ``ax``."""
    from matplotlib.patches import Circle, Polygon, Rectangle

    L = arena.size_mm
    ax.add_patch(Rectangle((0, 0), L, L, fill=False, lw=2.0, ec="black"))
    for ob in arena.obstacles:
        if ob.is_circle:
            patch = Circle(ob.centre, ob.radius, fc="0.55", ec="black", lw=1.0)
        else:
            patch = Polygon(ob.vertices, closed=True, fc="0.55", ec="black", lw=1.0)
        ax.add_patch(patch)
    bx, by = arena.ball
    if target_zone:
        ax.add_patch(Circle(arena.ball, arena.target_radius_mm, fc="none", ec="tab:red", ls="--", lw=0.8))
    ax.add_patch(Circle(arena.ball, arena.ball_radius_mm, fc="tab:red", ec="darkred", zorder=5))
    sx, sy, sh = arena.start
    ax.add_patch(Circle((sx, sy), ROBOT_RADIUS_MM, fc="none", ec="tab:green", lw=1.5))
    ax.annotate("start", (sx, sy), xytext=(sx + 150, sy - 60), color="tab:green", fontsize=8)
    if numbers:
        for i, (x, y, h) in enumerate(arena.positions):
            ax.plot([x, x + 90 * math.cos(h)], [y, y + 90 * math.sin(h)], color="tab:blue", lw=0.8)
            ax.plot(x, y, "o", ms=2.5, color="tab:blue")
            ax.annotate(str(i), (x, y), xytext=(x + 25, y + 25), fontsize=6, color="tab:blue")
    ax.set_xlim(-50, L + 50)
    ax.set_ylim(-50, L + 50)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")


def draw_robot(ax, world, rays: bool = True) -> None:
    """Draw the robot of ``world`` at its pose, with its IR rays (red where they see something)."""
    from matplotlib.patches import Circle

    x, y, h = world.pose
    ax.add_patch(Circle((x, y), ROBOT_RADIUS_MM, fc="khaki", ec="black", lw=1.0, zorder=6))
    ax.plot([x, x + ROBOT_RADIUS_MM * math.cos(h)], [y, y + ROBOT_RADIUS_MM * math.sin(h)], color="black", lw=1.5, zorder=7)
    if rays:
        for a, reach, hit in world.ray_hits():
            c, s = math.cos(h + a), math.sin(h + a)
            end = reach if hit is None else hit
            ax.plot([x + ROBOT_RADIUS_MM * c, x + end * c], [y + ROBOT_RADIUS_MM * s, y + end * s],
                    color="tab:red" if hit is not None else "tab:orange", lw=1.0, zorder=6)


def render_arena(arena: Arena, path, pose=None, title: str | None = None) -> Path:
    """Write a PNG of ``arena`` with the robot and its IR rays at ``pose`` (default: the start)."""
    from sim_world.world import World

    plt = _plt()
    world = World(arena)
    if pose is not None:
        world.place(pose)
    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    draw_arena(ax, arena)
    draw_robot(ax, world)
    state = world.state()
    ax.set_title(title or f"arena {arena.name!r}: {len(arena.obstacles)} obstacles; "
                 f"robot state {state:08b} (x7..x0)", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_trajectory(arena: Arena, trajectory, path, title: str | None = None, numbers: bool = False) -> Path:
    """Write a PNG of a run: ``trajectory`` is a list of (x, y, heading, event) as recorded by
    ``run_course(..., record=True)``; event "crash" is marked with a red x, "target" with a red
    dot, "relocate" starts a new leg (a blue square, no line drawn across the jump)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    draw_arena(ax, arena, numbers=numbers)
    xs: list[float] = []
    ys: list[float] = []
    crashes, relocs = [], []

    def flush():
        if len(xs) > 1:
            ax.plot(xs, ys, color="tab:purple", lw=0.6, alpha=0.8)

    for x, y, _h, event in trajectory:
        if event == "relocate":
            flush()
            xs, ys = [], []
            relocs.append((x, y))
        xs.append(x)
        ys.append(y)
        if event == "crash":
            crashes.append((x, y))
    flush()
    if trajectory:
        x, y, _h, _e = trajectory[-1]
        ax.plot(x, y, "*", ms=10, color="black", label="end", zorder=8)
    if relocs:
        ax.plot(*zip(*relocs), "s", ms=3, color="tab:blue", label=f"relocations ({len(relocs)})")
    if crashes:
        ax.plot(*zip(*crashes), "x", ms=6, mew=1.5, color="red", label=f"crashes ({len(crashes)})", zorder=8)
    if trajectory:
        ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title or f"trajectory, {len(trajectory)} poses", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--out", type=Path, default=Path("results"), metavar="DIR", help="folder of the pictures")
    parser.add_argument("--arena", action="append", metavar="NAME|FILE",
                        help=f"arena(s) to render, repeatable (default: all of {', '.join(ARENAS)})")
    return parser


def run_from_args(args) -> int:
    arenas = [load_arena(name) for name in args.arena or ARENAS]  # every file checked first
    for arena in arenas:
        # The picture is named after the arena's name, never its path (an absolute path in the
        # name would make a nested folder under --out).
        stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in arena.name) or "arena"
        path = render_arena(arena, Path(args.out) / f"arena_{stem}.png")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":  # the module alone; ``ehw arena`` adds the input checks and the lock
    import argparse

    raise SystemExit(run_from_args(add_arguments(argparse.ArgumentParser(prog="python -m sim_world.render")).parse_args()))
