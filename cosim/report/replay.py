"""``ehw replay RUN_DIR``: a lifetime as a video (``replay.mp4``; ``replay.gif`` without ffmpeg).

Each frame shows the arena (drawn once by ``sim_world.render.draw_arena``), the robot disc with
its heading, its ten IR rays (red where the sensor's obstacle bit is 1 in the state sensed at
that pose), the trail (the current leg darker), the crashes (red x) and the targets reached
(green dots), and a caption: the interaction count, the targets reached, the phase (execution, or
a learning phase with its reason, which ends in a download) and the downloads so far.

A lifetime longer than ``fps * max_seconds`` frames is sampled evenly (the trail and the marks
still show every interaction); when the sample has room, the frame of every learning phase is
kept. Frames are drawn with matplotlib's blitting (the arena is rendered once, each frame redraws
only the robot, rays, trail, marks and caption) and encoded by imageio-ffmpeg (H.264, yuv420p,
which browsers play) or, where that is missing, written as a GIF by Pillow.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

from base.errors import UserError
from ga.motions import OBSTACLE_MASK
from sim_world.arena import ROBOT_RADIUS_MM, load_arena
from sim_world.recording import RECORDING, Recording, load_recording
from sim_world.render import draw_arena
from sim_world.world import IR_SENSORS, SENSOR_REACH_MM, World

DEFAULT_FPS = 15
DEFAULT_MAX_SECONDS = 30.0
FRAME_PX = (640, 720)  # width, height: multiples of 16 (H.264 macro blocks)
_DPI = 100


class ReplayError(UserError, ValueError):
    """A run folder without what a replay needs."""


def ffmpeg_available() -> bool:
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return False
    return True


def frame_indices(rec: Recording, fps: float, max_seconds: float) -> np.ndarray:
    """The trajectory entries drawn as frames: all of them when they fit in ``max_seconds`` at
    ``fps``, else an even sample (with every learning phase's entry when there is room)."""
    n = len(rec.pose)
    budget = max(2, int(fps * max_seconds))
    if n <= budget:
        return np.arange(n)
    sample = np.unique(np.linspace(0, n - 1, budget).round().astype(np.int64))
    with_phases = np.union1d(sample, phase_entries(rec))
    if len(with_phases) <= budget * 1.1:
        return with_phases
    return sample


def phase_entries(rec: Recording) -> np.ndarray:
    """For each learning phase, the trajectory entry it followed (the failing interaction's)."""
    return np.searchsorted(rec.interaction, rec.phase_interaction, side="right") - 1


def sensed_states(rec: Recording, arena) -> np.ndarray:
    """The states of the recording; where it has none (an off-line run's noise-free path), the
    noise-free world senses them again at each pose."""
    if rec.has_states:
        return rec.state
    world = World(arena)
    return np.array([world.place(tuple(float(v) for v in p)) for p in rec.pose], dtype=np.uint8)


def _trail(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x and y of every pose with a NaN before each relocation (no line across the jump), and
    for each entry its position in those arrays."""
    relocs = rec.events("relocate")
    x = np.insert(rec.pose[:, 0].astype(float), relocs, np.nan)
    y = np.insert(rec.pose[:, 1].astype(float), relocs, np.nan)
    position = np.arange(len(rec.pose)) + np.searchsorted(relocs, np.arange(len(rec.pose)), side="right")
    return x, y, position


class _Scene:
    """The figure with the static arena rendered once, and the artists each frame moves."""

    def __init__(self, rec: Recording, arena, title: str):
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import LineCollection
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle, Rectangle

        self.fig = Figure(figsize=(FRAME_PX[0] / _DPI, FRAME_PX[1] / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.ax = self.fig.add_axes((0.02, 0.02, 0.96, 0.84))
        draw_arena(ax, arena, numbers=False)
        ax.set_axis_off()
        self.fig.text(0.5, 0.975, title, ha="center", va="top", fontsize=10, weight="bold")
        anim = {"animated": True}
        self.trail_all, = ax.plot([], [], color="tab:purple", lw=0.7, alpha=0.45, **anim)
        self.trail_leg, = ax.plot([], [], color="tab:purple", lw=1.2, **anim)
        self.targets, = ax.plot([], [], "o", ms=4, color="tab:green", zorder=8, **anim)
        self.crashes, = ax.plot([], [], "x", ms=7, mew=1.8, color="red", zorder=9, **anim)
        self.rays = LineCollection([], lw=1.4, zorder=6, **anim)
        ax.add_collection(self.rays)
        self.rays.set_clip_path(Rectangle((0, 0), arena.size_mm, arena.size_mm, transform=ax.transData))
        self.robot = Circle((0, 0), ROBOT_RADIUS_MM, fc="khaki", ec="black", lw=1.0, zorder=7, **anim)
        ax.add_patch(self.robot)
        self.heading, = ax.plot([], [], color="black", lw=2.0, zorder=8, **anim)
        self.artists = (self.trail_all, self.trail_leg, self.targets, self.crashes, self.rays,
                        self.robot, self.heading)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        # The caption changes every frame: Pillow draws it on the frame (matplotlib's text
        # rendering would take two thirds of a frame's time), in matplotlib's own mono font.
        from matplotlib import font_manager
        from PIL import ImageFont

        self.font = ImageFont.truetype(font_manager.findfont("DejaVu Sans Mono"), 13)
        self.caption, self.caption_colour = "", "black"

    def draw(self) -> np.ndarray:
        from PIL import Image, ImageDraw

        self.canvas.restore_region(self.background)
        for artist in self.artists:
            self.fig.draw_artist(artist)
        image = Image.fromarray(np.asarray(self.canvas.buffer_rgba())[:, :, :3])
        ImageDraw.Draw(image).multiline_text((20, 40), self.caption, fill=self.caption_colour,
                                             font=self.font, spacing=4)
        return np.asarray(image)


def _ray_segments(pose, state: int) -> tuple[list, list]:
    x, y, h = (float(v) for v in pose)
    segments, colours = [], []
    for angle_deg, bit in IR_SENSORS:
        a = h + math.radians(angle_deg)
        c, s = math.cos(a), math.sin(a)
        segments.append([(x + ROBOT_RADIUS_MM * c, y + ROBOT_RADIUS_MM * s),
                         (x + SENSOR_REACH_MM * c, y + SENSOR_REACH_MM * s)])
        lit = state != 255 and (state & OBSTACLE_MASK) >> bit & 1
        colours.append("red" if lit else (0.6, 0.6, 0.6, 0.6))
    return segments, colours


def frames(rec: Recording, arena, indices: np.ndarray, n_targets: int | None = None, title: str = ""):
    """Yield the RGB frames (H, W, 3 uint8) of the trajectory entries ``indices``."""
    states = sensed_states(rec, arena)
    tx, ty, position = _trail(rec)
    crash_at = rec.events("crash")
    target_at = rec.events("target")
    starts = np.union1d(rec.events("relocate"), [0])
    phase_at = phase_entries(rec)
    total = int(rec.interaction[-1]) if len(rec.interaction) else 0
    scene = _Scene(rec, arena, title)
    online = rec.method.startswith("online")  # the off-line path has no phases nor downloads
    previous = -1
    for i in indices:
        i = int(i)
        x, y, h = (float(v) for v in rec.pose[i])
        p = position[i] + 1
        leg_start = position[starts[np.searchsorted(starts, i, side="right") - 1]]
        scene.trail_all.set_data(tx[:p], ty[:p])
        scene.trail_leg.set_data(tx[leg_start:p], ty[leg_start:p])
        c = crash_at[crash_at <= i]
        scene.crashes.set_data(rec.pose[c, 0], rec.pose[c, 1])
        t = target_at[target_at <= i]
        scene.targets.set_data(rec.pose[t, 0], rec.pose[t, 1])
        scene.robot.center = (x, y)
        scene.heading.set_data([x, x + ROBOT_RADIUS_MM * math.cos(h)], [y, y + ROBOT_RADIUS_MM * math.sin(h)])
        segments, colours = _ray_segments(rec.pose[i], int(states[i]))
        scene.rays.set_segments(segments)
        scene.rays.set_color(colours)
        learned = np.flatnonzero((phase_at > previous) & (phase_at <= i))
        downloads = 1 + int(np.sum(phase_at <= i))  # the first controller, then one per phase
        if learned.size:
            k = learned[-1]
            more = f" (+{learned.size - 1} since the last frame)" if learned.size > 1 else ""
            phase = f"LEARNING {k + 1} after a {rec.phase_reason[k]} -> download {downloads}{more}"
            scene.caption_colour = "darkorange"
        else:
            phase = "execution"
            scene.caption_colour = "black"
        goal = f"/{n_targets}" if n_targets else ""
        learning = (f"phase: {phase}\ndownloads {downloads}   " if online else
                    "the best controller of the evolution, in the noise-free world\n")
        scene.caption = (
            f"interaction {int(rec.interaction[i]):>6,} of {total:,}   targets {len(t)}{goal}   "
            f"crashes {len(c)}\n{learning}state {int(states[i]):08b} (x7..x0)")
        previous = i
        yield scene.draw()


def write_video(rec: Recording, arena, path: Path, fps: float = DEFAULT_FPS,
                max_seconds: float = DEFAULT_MAX_SECONDS, n_targets: int | None = None,
                title: str = "", progress: bool = True) -> Path:
    """Render the replay into ``path`` (.mp4 with imageio-ffmpeg, else .gif), atomically: a
    stopped render leaves no partial file."""
    import imageio.v2 as imageio

    path = Path(path)
    indices = frame_indices(rec, fps, max_seconds)
    partial = path.with_name(f".{path.stem}.partial{path.suffix}")
    if path.suffix == ".mp4":
        writer = imageio.get_writer(partial, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    pixelformat="yuv420p", quality=6, macro_block_size=16,
                                    ffmpeg_log_level="error")
        step = 1
    else:  # Pillow's GIF: half size, at most 10 frames a second
        step = max(1, math.ceil(fps / 10))
        writer = imageio.get_writer(partial, format="GIF", mode="I", duration=1000 * step / fps, loop=0)
    from tqdm import tqdm

    try:
        with writer:
            for frame in tqdm(frames(rec, arena, indices[::step], n_targets, title), total=len(indices[::step]),
                              unit="frame", desc="replay", file=sys.stderr, disable=not progress):
                writer.append_data(frame if path.suffix == ".mp4" else frame[::2, ::2])
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def replay(run_dir: Path, fps: float = DEFAULT_FPS, max_seconds: float = DEFAULT_MAX_SECONDS,
           fmt: str = "auto", progress: bool = True, out: Path | None = None) -> Path:
    """Render ``run_dir``'s lifetime to ``run_dir/replay.mp4`` (or ``.gif``); returns the file."""
    run_dir = Path(run_dir)
    if not (run_dir / RECORDING).is_file():
        raise ReplayError(f"{str(run_dir)!r} holds no {RECORDING} (a run of `ehw sim` or `ehw offline` "
                          "writes it with its summary.json)")
    rec = load_recording(run_dir)
    if len(rec.pose) == 0:
        raise ReplayError(f"{str(run_dir / RECORDING)!r} holds no poses")
    if fmt == "auto":
        fmt = "mp4" if ffmpeg_available() else "gif"
    arena = load_arena(rec.arena)
    n_targets = _n_targets(run_dir)
    what = "on-line model-based lifetime" if rec.method.startswith("online") else "best model-free controller"
    title = f"{what}, seed {rec.seed}, arena {arena.name!r}"
    return write_video(rec, arena, Path(out) if out else run_dir / f"replay.{fmt}", fps, max_seconds,
                       n_targets, title, progress)


def _n_targets(run_dir: Path) -> int | None:
    import json

    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        return int(summary["config"]["n_targets"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
