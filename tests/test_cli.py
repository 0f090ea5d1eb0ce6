"""`ehw`: one command line, runs that never lose or mix results, every bad input one `error:` line.

One test per case of issue 15 (each failed before it: a traceback, a run that went ahead, a result
overwritten), run in-process through ``cosim.cli.main.main`` in a temporary working directory.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO_ROOT, one_error

from base.runs import LATEST, RunLock

TINY = ["--arena", "empty", "--targets", "1", "--population", "20", "--quiet", "--no-plots"]


# -- the console script ---------------------------------------------------------------------------


def test_help_lists_the_subcommands(ehw):
    status, out, _ = ehw("--help")
    assert status == 0 and "sim" in out
    import cosim.cli.main

    text = cosim.cli.main.build_parser().format_help()
    for name in ("sim", "offline", "compare", "verilog", "bench", "arena", "baseline", "limit"):
        assert f"    {name} " in text, name


def test_every_sim_option_has_help_and_its_default(ehw, capsys):
    import cosim.cli.main

    cosim.cli.main.build_parser()
    sub = cosim.cli.main._SUBPARSERS["sim"]
    for action in sub._actions:
        if action.option_strings and action.dest != "help":
            assert action.help, action.dest
    text = sub.format_help()
    assert "--population POPULATION" in text and "(default: 500)" in text
    for flag in ("--seed", "--out", "--resume", "--force", "--quiet", "--config", "--simulator",
                 "--hdl-sample", "--waves", "--clock-hz"):
        assert flag in text, flag
    for name in ("offline", "baseline"):  # the shared flags, spelled the same
        text = cosim.cli.main._SUBPARSERS[name].format_help()
        assert "--out DIR" in text and "--config FILE" in text


def test_console_script_and_make_use_one_simulator(monkeypatch):
    """`ehw sim --backend cocotb` and `make sim BACKEND=cocotb` ran Icarus and Verilator."""
    import argparse

    from cosim.cli.options import resolve_hdl_settings

    monkeypatch.delenv("EHW_SIM", raising=False)
    monkeypatch.delenv("EHW_HDL_SAMPLE", raising=False)
    plain = argparse.Namespace(backend="cocotb", simulator=None, hdl_sample=None, waves=None, clock_hz=None)
    assert resolve_hdl_settings(plain)["simulator"] == "verilator"
    assert resolve_hdl_settings(plain)["hdl_sample"] == 0
    monkeypatch.setenv("EHW_SIM", "icarus")  # the environment remains a fallback
    assert resolve_hdl_settings(plain) == {**resolve_hdl_settings(plain), "simulator": "icarus", "hdl_sample": 1}
    make = subprocess.run(["make", "-n", "-s", "sim", "BACKEND=cocotb"], cwd=REPO_ROOT, capture_output=True,
                          text=True, env={**os.environ, "EHW_SIM": ""})
    line = next(l for l in make.stdout.splitlines() if "ehw sim" in l)
    assert "--backend cocotb" in line and "EHW_SIM" not in line and "--simulator" not in line


# -- results never lost or mixed ------------------------------------------------------------------


def test_two_runs_without_out_keep_both(ehw, tmp_path):
    """`make sim` twice: the second replaced the first's checkpoint."""
    assert ehw("sim", *TINY)[0] == 0
    first = (tmp_path / "results/model_based" / LATEST).resolve()
    time.sleep(1.1)  # another second: another folder name (a clash gets a suffix anyway)
    assert ehw("sim", *TINY, "--seed", "2")[0] == 0
    second = (tmp_path / "results/model_based" / LATEST).resolve()
    assert first != second and first.parent == second.parent
    assert json.loads((first / "summary.json").read_text())["seed"] == 1
    assert json.loads((second / "summary.json").read_text())["seed"] == 2
    assert (first / "checkpoint.json").exists() and (second / "checkpoint.json").exists()
    assert second.name.endswith("-seed2")


def test_out_holding_a_run_is_refused(ehw, tmp_path):
    """Two runs into one --out both printed "wrote"; only one result survived."""
    assert ehw("sim", *TINY, "--out", "run")[0] == 0
    before = (tmp_path / "run/summary.json").read_bytes()
    status, out, err = ehw("sim", *TINY, "--seed", "3", "--out", "run")
    one_error(status, err, "'run'", "already holds a run", "--resume", "--force")
    assert "wrote" not in out
    assert (tmp_path / "run/summary.json").read_bytes() == before


def test_force_replaces_and_leaves_no_stale_plot(ehw, tmp_path):
    """`--no-plots` left the previous run's PNGs beside the new summary."""
    assert ehw("sim", "--arena", "empty", "--targets", "1", "--population", "20", "--quiet",
               "--out", "run")[0] == 0
    assert list((tmp_path / "run").glob("*.png"))
    assert ehw("sim", *TINY, "--seed", "4", "--out", "run", "--force")[0] == 0
    assert not list((tmp_path / "run").glob("*.png"))
    assert json.loads((tmp_path / "run/summary.json").read_text())["seed"] == 4
    # The same when a run is resumed without plots: no figure of an earlier session stays.
    # (Seed 1 has learning phases, so a checkpoint, with one target.)
    assert ehw("sim", "--arena", "empty", "--targets", "1", "--population", "20", "--quiet",
               "--out", "run2")[0] == 0
    assert len(list((tmp_path / "run2").glob("*.png"))) == 2
    assert ehw("sim", "--resume", "--out", "run2", "--quiet", "--no-plots")[0] == 0
    assert not list((tmp_path / "run2").glob("*.png"))
    assert {p.name for p in (tmp_path / "run2").iterdir()} == {
        ".lock", "checkpoint.json", "config.toml", "sessions.json", "summary.json", "lifetime.npz"}


def test_a_folder_in_use_is_refused_and_a_dead_lock_taken_over(ehw, tmp_path):
    folder = tmp_path / "busy"
    folder.mkdir()
    with RunLock(folder):
        status, _, err = ehw("sim", *TINY, "--out", folder)
    one_error(status, err, str(folder), "in use by process", str(os.getpid()))
    # A lock file left by a process that died (kill -9): the kernel dropped its lock.
    (folder / ".lock").write_text(json.dumps({"pid": 999_999_999, "command": "ehw sim"}))
    assert ehw("sim", *TINY, "--out", folder)[0] == 0


def test_two_sim_processes_on_one_folder(tmp_path):
    """Two `ehw sim` on one --out at once: one runs, the other is refused (the folder and the
    other process named); without --out, both run, each in its own folder."""
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    command = [sys.executable, "-m", "cosim.cli.main", "sim", *TINY]
    procs = [subprocess.Popen(command + ["--out", "shared"], cwd=tmp_path, env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE) for _ in range(2)]
    procs += [subprocess.Popen(command + ["--seed", str(s)], cwd=tmp_path, env=env, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE) for s in (5, 6)]
    results = [(p.wait(timeout=120), *p.communicate()) for p in procs]
    shared = sorted(results[:2], key=lambda r: r[0])
    assert shared[0][0] == 0, shared[0][2]
    one_error(shared[1][0], shared[1][2], "'shared'")
    assert ("in use by process" in shared[1][2]) or ("already holds a run" in shared[1][2])
    sessions = json.loads((tmp_path / "shared/sessions.json").read_text())
    assert len(sessions) == 1
    assert [r[0] for r in results[2:]] == [0, 0], [r[2] for r in results[2:]]
    folders = [p.name for p in (tmp_path / "results/model_based").iterdir() if p.name != LATEST]
    assert sorted(name.rsplit("-", 1)[1] for name in folders) == ["seed5", "seed6"], folders


# -- every input checked before any work ----------------------------------------------------------


@pytest.mark.parametrize("args, words", [
    (["--loop-window", "-3"], ["--loop-window", "-3"]),  # ran forever, ignoring --max-interactions
    (["--max-interactions", "-1"], ["--max-interactions"]),  # a 0-interaction "lifetime", exit 0
    (["--loop-radius-mm", "nan"], ["--loop-radius-mm", "nan"]),  # failed at the first save
    (["--loop-still-mm", "inf"], ["--loop-still-mm", "inf"]),
    (["--population", "0"], ["population"]),
    (["--seed", "x"], ["--seed", "'x'"]),
    (["--clock-hz", "-5"], ["--clock-hz"]),
    (["--blind-bit", "9", "--blind-after-target", "1"], ["blind", "9"]),
])
def test_bad_options_are_refused_before_any_work(ehw, tmp_path, args, words):
    status, _, err = ehw("sim", *TINY, *args)
    one_error(status, err, *words)
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("name, value", [("EHW_CLOCK_HZ", "abc"), ("EHW_SIM", "modelsim"),
                                         ("EHW_HDL_SAMPLE", "some"), ("WAVES", "maybe")])
def test_bad_environment_is_refused_at_startup(ehw, tmp_path, monkeypatch, name, value):
    """EHW_CLOCK_HZ=abc was read after the whole run, which then ended in a traceback."""
    monkeypatch.setenv(name, value)
    status, _, err = ehw("sim", *TINY)
    one_error(status, err, name, repr(value))
    assert not (tmp_path / "results").exists()


def _arena_file(tmp_path, **changes) -> Path:
    from sim_world.arena import ARENA_DIR

    data = json.loads((ARENA_DIR / "empty.json").read_text())
    data.update(changes)
    path = tmp_path / "arena.json"
    path.write_text(json.dumps(data))
    return path


def test_bad_files_end_as_one_error_line(ehw, tmp_path):
    """Arena, config, checkpoint and file errors ended as 20-line tracebacks."""
    (tmp_path / "broken.json").write_text("{not json")
    one_error(*ehw("sim", *TINY, "--arena", tmp_path / "broken.json")[::2], "broken.json", "not valid JSON")
    arena = _arena_file(tmp_path, ball_radius_mm=-100)
    one_error(*ehw("sim", *TINY, "--arena", arena)[::2], "ball_radius_mm", "-100")
    one_error(*ehw("offline", "--arena", arena, "--quiet")[::2], "ball_radius_mm")
    one_error(*ehw("baseline", "--arena", arena)[::2], "ball_radius_mm")
    one_error(*ehw("arena", "--arena", arena)[::2], "ball_radius_mm")
    (tmp_path / "out_is_a_file").write_text("x")
    one_error(*ehw("sim", *TINY, "--out", "out_is_a_file")[::2], "out_is_a_file", "is a file")
    assert not (tmp_path / "results").exists()


def test_compare_adaptation_only_checks_its_input_first(ehw, tmp_path):
    """compare --adaptation-only ran all its lifetimes before finding its input file missing."""
    t0 = time.perf_counter()
    status, _, err = ehw("compare", "--adaptation-only", "--blind-bit", "0", "--blind-after-target", "2",
                         "--out", "nothing")
    one_error(status, err, "nothing/compare.json")
    assert time.perf_counter() - t0 < 5
    assert not (tmp_path / "nothing/compare").exists()


def test_offline_resume_without_a_checkpoint_is_refused(ehw, tmp_path):
    """offline --resume without a checkpoint silently started afresh."""
    (tmp_path / "run").mkdir()
    one_error(*ehw("offline", "--resume", "--out", "run", "--quiet")[::2], "'run'", "checkpoint.json")
    one_error(*ehw("sim", "--resume", *TINY)[::2], "latest")
    assert list((tmp_path / "run").iterdir()) == []  # a failed start leaves the folder as it was


def test_render_of_an_arena_path_writes_beside_the_others(ehw, tmp_path):
    """`--arena /abs/x.json` wrote into a nested folder results/arena_/abs/..."""
    arena = _arena_file(tmp_path, name="mine")
    status, out, _ = ehw("arena", "--arena", arena.resolve(), "--out", "pictures")
    assert status == 0
    assert [p.name for p in (tmp_path / "pictures").rglob("*.png")] == ["arena_mine.png"]


# -- checkpoints: a checksum, and the stored config used on resume --------------------------------


def _edit_checkpoint(path: Path, edit) -> None:
    payload = json.loads(path.read_text())
    edit(payload)
    path.write_text(json.dumps(payload))


@pytest.mark.parametrize("edit", [
    lambda p: p["state"].update(generations=p["state"]["generations"] + 100),
    lambda p: p["state"]["phases"].pop(),
    lambda p: p["config"].update(population=40),  # was reported, and not used
])
def test_a_hand_edited_checkpoint_is_refused(ehw, tmp_path, edit):
    assert ehw("sim", *TINY, "--targets", "3", "--out", "run")[0] == 0
    _edit_checkpoint(tmp_path / "run/checkpoint.json", edit)
    status, _, err = ehw("sim", "--resume", "--out", "run", "--quiet", "--no-plots")
    one_error(status, err, "checkpoint.json", "checksum")


def test_resume_uses_the_stored_config(ehw, tmp_path):
    assert ehw("sim", *TINY, "--targets", "2", "--seed", "7", "--out", "run")[0] == 0
    whole = json.loads((tmp_path / "run/summary.json").read_text())
    # No options given: the stored config (seed 7, population 20, 2 targets) is the one used.
    assert ehw("sim", "--resume", "--out", "run", "--quiet", "--no-plots")[0] == 0
    again = json.loads((tmp_path / "run/summary.json").read_text())
    assert again["config"] == whole["config"] and again["interactions"] == whole["interactions"]
    one_error(*ehw("sim", "--resume", "--out", "run", "--population", "30")[::2], "--population 30", "stored 20")
    sessions = json.loads((tmp_path / "run/sessions.json").read_text())
    assert [s["resumed"] for s in sessions] == [False, True]


# -- config files -----------------------------------------------------------------------------------


def test_config_file_flags_override_and_summary_reruns(ehw, tmp_path):
    (tmp_path / "run.toml").write_text('arena = "empty"\nn_targets = 2\npopulation = 20\nseed = 9\n'
                                       "tournament = 5\n")
    assert ehw("sim", "--config", "run.toml", "--seed", "3", "--out", "a", "--quiet", "--no-plots")[0] == 0
    a = json.loads((tmp_path / "a/summary.json").read_text())
    assert a["config"]["seed"] == 3 and a["config"]["population"] == 20 and a["config"]["tournament"] == 5
    assert a["config"]["n_targets"] == 2
    # The run's config.toml (and its summary.json) re-run it exactly.
    for source in ("a/config.toml", "a/summary.json"):
        out = source.replace("/", "_")
        assert ehw("sim", "--config", source, "--out", out, "--quiet", "--no-plots")[0] == 0
        b = json.loads((tmp_path / out / "summary.json").read_text())
        assert b["config"] == a["config"] and b["best_genome"] == a["best_genome"]
        assert b["interactions"] == a["interactions"]


@pytest.mark.parametrize("text, words", [
    ("populaton = 20\n", ["'populaton'", "did you mean 'population'"]),
    ('population = "big"\n', ["'population'", "an integer"]),
    ("loop_radius_mm = nan\n", ["'loop_radius_mm'", "finite"]),
    ('backend = "vhdl"\n', ["'backend'", "'reference'"]),
    ("seed = 1\nseed = 2\n", ["not valid TOML"]),
    ("noise = 1\n", ["'noise'", "true/false"]),
])
def test_config_file_errors_name_the_key(ehw, tmp_path, text, words):
    (tmp_path / "bad.toml").write_text(text)
    one_error(*ehw("sim", "--config", "bad.toml", *TINY)[::2], "bad.toml", *words)
    assert not (tmp_path / "results").exists()


# -- the Gymnasium environment keeps Gymnasium's conventions --------------------------------------


def test_gym_env_conventions():
    import warnings

    from gymnasium.error import ResetNeeded

    from sim_world.gym_env import EHWTrackingEnv

    env = EHWTrackingEnv(arena="empty", max_leg_steps=3)
    with pytest.raises(ResetNeeded):
        env.step(0)
    env.reset(seed=0)
    pose = env.world.pose
    with pytest.raises(ValueError, match="True"):
        env.step(True)  # was taken as motion 1
    assert env.world.pose == pose and env.world.interactions == 0
    with pytest.raises(ValueError, match="colour"):
        env.reset(options={"colour": "red"})
    env.reset(options={})
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(2)
    assert truncated
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        after = env.step(2)
    assert any("reset()" in str(w.message) for w in caught)
    assert after[0] == obs and after[1] == 0.0 and after[3] and info["interactions"] == after[4]["interactions"]


def test_offline_resume_keeps_the_run_options(ehw, tmp_path):
    tiny = ["--arena", "empty", "--max-leg-steps", "40", "--quiet", "--no-plots"]
    assert ehw("offline", *tiny, "--seed", "3", "--generations-cap", "1", "--out", "run")[0] == 0
    # Resumed with no options: the seed, arena and step limit stored with the run are used.
    assert ehw("offline", "--resume", "--out", "run", "--generations-cap", "2")[0] == 0
    summary = json.loads((tmp_path / "run/summary.json").read_text())
    assert summary["seed"] == 3 and summary["generations"] == 2
    config = (tmp_path / "run/config.toml").read_text()
    one_error(*ehw("offline", "--resume", "--out", "run", "--seed", "4")[::2], "seed: saved 3, now 4")
    assert (tmp_path / "run/config.toml").read_text() == config


def test_a_fresh_run_that_fails_leaves_no_folder(ehw, tmp_path, monkeypatch):
    assert ehw("sim", *TINY)[0] == 0
    before = (tmp_path / "results/model_based" / LATEST).resolve()
    from cosim.boards.interfaces import BackendUnavailable

    def unavailable(*args, **kwargs):
        raise BackendUnavailable("backend 'reference' is not available (a test)")

    monkeypatch.setattr("cosim.online.run.make_boards", unavailable)
    one_error(*ehw("sim", *TINY, "--seed", "2")[::2], "not available")
    assert [p for p in (tmp_path / "results/model_based").iterdir() if p.name != LATEST] == [before]
    assert (tmp_path / "results/model_based" / LATEST).resolve() == before
