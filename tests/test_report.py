"""``ehw replay`` and ``ehw report`` (cosim.report): the recording, the video, the HTML page, and
the page as a person sees it in headless Chromium (tests/test_report.py::test_report_in_chromium)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cosim.cli.main import main
from cosim.online.config import OnlineConfig
from cosim.online.report import recording_of
from cosim.online.run import make_run
from cosim.report.html import REPORT, write_report
from cosim.report.replay import ffmpeg_available, frame_indices, replay
from sim_world.recording import EVENTS, load_recording, trajectory_arrays, write_recording

SMALL = dict(arena="one_obstacle", n_targets=3, population=40, tournament=5, generations_per_phase=3,
             max_leg_steps=300, loop_window=60)
ROOT = Path(__file__).resolve().parents[1]
needs_ffmpeg = pytest.mark.skipif(not ffmpeg_available(), reason="imageio-ffmpeg is not installed")


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory) -> Path:
    """A short lifetime through ``ehw sim``, which writes its report at the end by default."""
    out = tmp_path_factory.mktemp("sim") / "run"
    argv = ["sim", "--seed", "4", "--arena", "one_obstacle", "--targets", "3", "--population", "40",
            "--generations-per-phase", "3", "--max-leg-steps", "300", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    return out


def test_the_recording_holds_every_interaction_and_a_resumed_run_records_the_same(tmp_path):
    config = OnlineConfig(seed=9, **SMALL)
    whole = make_run(config).run()
    rec = recording_of(whole)
    assert len(rec["pose"]) == 1 + whole.interactions + whole.targets  # start, steps, relocations
    assert rec["interaction"][-1] == whole.interactions == len(rec["motions"])
    assert int(np.sum(rec["event"] == EVENTS.index("crash"))) == whole.summary()["crashes"]
    assert rec["pose"].dtype == np.float32 and rec["state"].dtype == np.uint8
    assert len(rec["phase_interaction"]) == len(whole.phases) >= 2
    make_run(config, out=tmp_path).run(stop_after_phases=2)
    resumed = make_run(config, out=tmp_path, resume=True).run()
    again = recording_of(resumed)
    assert rec.keys() == again.keys()
    for key in rec:
        assert np.array_equal(rec[key], again[key]), key
    # And the file round-trips.
    write_recording(rec, tmp_path)
    loaded = load_recording(tmp_path)
    assert np.array_equal(loaded.pose, rec["pose"]) and loaded.arena == "one_obstacle" and loaded.seed == 9


def test_long_lifetimes_are_sampled_to_the_budget_and_keep_their_phases():
    n = 5000
    trajectory = [(0.0, 0.0, 0.0, 0, "start")] + [(float(i), 0.0, 0.0, 0, "") for i in range(1, n)]
    rec = load_like(trajectory_arrays(trajectory), phases=[100, 2000, 4000])
    idx = frame_indices(rec, fps=10, max_seconds=20)
    assert len(idx) <= 220 and idx[0] == 0 and idx[-1] == n - 1
    assert {100, 2000, 4000} <= set(idx.tolist())
    assert len(frame_indices(rec, fps=10, max_seconds=600)) == n  # fits: every entry


def load_like(arrays: dict, phases: list[int]):
    from sim_world.recording import Recording

    empty = {"motions": np.zeros(0, np.uint8), "curve_states": np.zeros(0, np.int32),
             "curve_transitions": np.zeros(0, np.int32), "phase_changed": np.zeros(len(phases), bool),
             "phase_reason": np.array(["crash"] * len(phases)), "transitions": np.zeros((0, 4), np.uint8),
             "phase_interaction": np.array(phases, np.int32)}
    return Recording(**{**empty, **arrays}, arena="default", seed=0, method="online-model-based")


@needs_ffmpeg
def test_the_mp4_decodes_to_its_frames_and_successive_frames_differ(sim_run, tmp_path):
    import imageio.v2 as imageio

    rec = load_recording(sim_run)
    video = replay(sim_run, fps=10, max_seconds=4, progress=False, out=tmp_path / "replay.mp4")
    expected = len(frame_indices(rec, fps=10, max_seconds=4))
    with imageio.get_reader(video, format="FFMPEG") as reader:
        frames = [np.asarray(f, dtype=np.int16) for f in reader]
    assert len(frames) == expected >= 30
    assert frames[0].shape == (720, 640, 3)
    changed = [np.abs(a - b).max() > 40 for a, b in zip(frames, frames[1:])]
    assert all(changed), f"frames {[i for i, c in enumerate(changed) if not c]} equal the next"


def test_the_gif_fallback_is_half_size_at_most_ten_frames_a_second(sim_run, tmp_path, capsys):
    import imageio.v2 as imageio

    gif = tmp_path / "replay.gif"
    assert main(["replay", str(sim_run), "--fps", "20", "--max-seconds", "2", "--quiet", "--out", str(gif)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {gif}"
    frames = imageio.mimread(gif)
    assert len(frames) == 20 and frames[0].shape[:2] == (360, 320)  # 40 frames at 20 fps, every second one


def test_sim_writes_a_self_contained_report(sim_run):
    html = (sim_run / REPORT).read_text()
    assert (sim_run / "replay.mp4").is_file() or (sim_run / "replay.gif").is_file()
    for part in ("Summary against the paper", "12,280", "Replay", "Learning curves", "World model",
                 "The evolved controller", "fig9_trajectory.png", "ehw sim --config"):
        assert part in html, part
    assert html.count("<td>0</td>") >= 1  # the terms table starts at row 0 ...
    assert "<td>49</td>" in html  # ... and has all 50 rows
    # Self-contained: nothing is fetched (no http(s), no file or relative src).
    srcs = [s.split('"', 1)[0] for s in html.split(' src="')[1:]]
    assert srcs and all(s.startswith("data:") for s in srcs)
    assert "http://" not in html and "https://" not in html and "<script" not in html


def test_offline_and_compare_reports(tmp_path):
    from cosim.offline.report import plot_results
    from ga.genome import hex_from_rows

    rows = np.random.default_rng(1).integers(0, 1 << 19, 50, dtype=np.uint32)
    out = tmp_path / "offline"
    out.mkdir()
    files = plot_results(out, [{"generation": 1, "best_steps": 10, "best_fitness": 0.5}], hex_from_rows(rows),
                         "default", 40, 2, seed=7)
    assert files["recording"] == "lifetime.npz" and not load_recording(out).has_states
    (out / "summary.json").write_text(json.dumps({"method": "offline-model-free", "seed": 7, "targets_reached": 0,
                                                  "interactions": 80, "best_genome": hex_from_rows(rows),
                                                  "config": {"reflex": True}}))
    html = write_report(out, max_seconds=2, progress=False).read_text()
    assert "Off-line model-free run" in html and "3,283,269" in html and "Replay" in html

    cmp = tmp_path / "compare"
    cmp.mkdir()
    stat = {"median": 800.0, "min": 700, "max": 900}
    (cmp / "compare.json").write_text(json.dumps({
        "arena": "default", "seeds": [1, 2], "paper": {"online": {"interactions": 12280}},
        "methods": {"baseline": {"interactions": stat}, "q-learning/shaped": {"interactions": stat}},
        "per_seed": {m: {"1": {"interactions": 700, "targets_reached": 64}, "2": {"interactions": 900,
                                                                                   "targets_reached": 60}}
                     for m in ("baseline", "q-learning/shaped")}}))
    from cosim.compare.report import write_boxplot

    assert write_boxplot(json.loads((cmp / "compare.json").read_text()), cmp / "compare_box.png")
    html = write_report(cmp, progress=False).read_text()
    assert "q-learning/shaped" in html and "800 [700, 900]" in html and 'alt="box plots"' in html


def test_command_line_errors_are_one_line(tmp_path, capsys):
    for argv, words in ((["replay", str(tmp_path / "none")], "no run folder"),
                        (["report", str(tmp_path)], "holds no run"),
                        (["replay", str(tmp_path)], "lifetime.npz"),
                        (["report", str(tmp_path), "--fps", "0"], "--fps"),
                        (["replay", str(tmp_path), "--out", "x.avi"], "x.avi")):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error:") and words in err[0], (argv, err)


def _chromium():
    """(playwright's sync API, Chromium's path), or a skip saying why neither can start."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (make browser-tools installs it and Debian's chromium)")
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        pytest.skip("no chromium on PATH (make browser-tools: apt-get install chromium)")
    return sync_playwright, path


BROWSER_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--no-first-run"]


def test_report_in_chromium(sim_run):
    """The page as a person opens it: it loads from disk with no console error and no failed
    request, every image has a size, the video plays; a screenshot goes to results/."""
    sync_playwright, path = _chromium()
    problems: list[str] = []
    with sync_playwright() as pw:
        try:
            browser = pw.chromium.launch(executable_path=path, args=BROWSER_ARGS)
        except Exception as exc:  # noqa: BLE001 - any failure to start is a reason to skip
            pytest.skip(f"chromium ({path}) does not start here: {str(exc).splitlines()[0]}")
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url[:80]}"))
            page.goto((sim_run / REPORT).resolve().as_uri(), wait_until="load")
            images = page.evaluate("() => Array.from(document.images).map(i => [i.alt, i.naturalWidth, i.naturalHeight])")
            assert len(images) >= 4
            assert all(w > 0 and h > 0 for _, w, h in images), images
            if (sim_run / "replay.mp4").is_file():
                video = page.evaluate("""async () => {
                    const v = document.querySelector('video');
                    if (v.readyState < 1) await new Promise(r => v.addEventListener('loadedmetadata', r, {once: true}));
                    const start = v.currentTime;
                    await v.play();
                    for (let waited = 0; v.currentTime <= start && waited < 10000; waited += 100)
                        await new Promise(r => setTimeout(r, 100));  // a loaded machine decodes late
                    return {duration: v.duration, start: start, now: v.currentTime, width: v.videoWidth,
                            height: v.videoHeight, error: v.error && v.error.code};
                }""")
                assert video["error"] is None and video["width"] > 0 and video["height"] > 0, video
                assert video["duration"] > 0 and video["now"] > video["start"], video
            shot = ROOT / "results" / "report" / "report_screenshot.png"
            shot.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(shot), full_page=True)
            assert shot.stat().st_size > 10_000
        finally:
            browser.close()
    assert problems == []
