"""What seeing a lifetime costs (issue 37): the lifetime, its recording, the replay and the report.

- ``lifetime_16_targets_s``: seed 1's 16-target lifetime on the reference backend (723
  interactions, tests/test_golden_lifetime.py), the loop alone (``OnlineRun.run``), best of 2;
  ``lifetime_interactions_per_s`` its rate. The loop keeps the replay's poses and states as it
  always kept its trajectory: this is the figure ``ehw sim`` keeps.
- ``write_results_s``: ``summary.json``, the figures and ``lifetime.npz``; ``recording_s`` the
  recording alone; ``recording_bytes`` its size.
- ``replay_s``, ``replay_frames``, ``replay_ms_per_frame``, ``replay_bytes``: ``ehw replay`` at its
  defaults (15 fps, at most 30 s); ``report_s`` and ``report_bytes``: ``ehw report`` once the
  video is there (the figures and the page).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path


def run() -> dict:
    from cosim.online.config import OnlineConfig
    from cosim.online.report import recording_of, write_results
    from cosim.online.run import make_run
    from cosim.report.html import write_report
    from cosim.report.replay import frame_indices, replay
    from sim_world.recording import load_recording, write_recording

    config = OnlineConfig(seed=1, n_targets=16)
    best, run = float("inf"), None
    for _ in range(2):
        run = make_run(config)
        t0 = time.perf_counter()
        run.run()
        best = min(best, time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        t0 = time.perf_counter()
        write_results(run, out)
        t_results = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_recording(recording_of(run), out)
        t_recording = time.perf_counter() - t0
        t0 = time.perf_counter()
        video = replay(out, progress=False)
        t_replay = time.perf_counter() - t0
        frames = len(frame_indices(load_recording(out), 15, 30))
        t0 = time.perf_counter()
        page = write_report(out, progress=False)
        t_report = time.perf_counter() - t0
        sizes = {"recording_bytes": (out / "lifetime.npz").stat().st_size, "replay_bytes": video.stat().st_size,
                 "report_bytes": page.stat().st_size}
    return {
        "lifetime_16_targets_s": round(best, 3),
        "lifetime_interactions": run.interactions,
        "lifetime_interactions_per_s": round(run.interactions / best, 1),
        "write_results_s": round(t_results, 3),
        "recording_s": round(t_recording, 4),
        "replay_s": round(t_replay, 2),
        "replay_frames": frames,
        "replay_ms_per_frame": round(1000 * t_replay / frames, 1),
        "report_s": round(t_report, 2),
        **sizes,
    }
