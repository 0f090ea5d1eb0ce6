"""`ehw compare`, `ehw baseline`, `ehw arena` and `ehw bench` (issue 15, second round): one option
table for `ehw compare`, every input checked before any work, and
run folders that keep every run (a fresh folder and `latest`; an `--out` holding a run refused).

Each test failed before this round: compare passed its arguments through (no --config, no
defaults in its help), baseline/arena/bench wrote fixed files that the next run replaced.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from conftest import one_error
from test_cli import _arena_file

from base.runs import LATEST

# A comparison of a second or two: the baseline on one seed, Q-learning capped at 200 interactions.
SMALL = ["--seeds", "1", "--methods", "baseline,q-learning", "--shaping", "shaped",
         "--max-interactions", "200", "--jobs", "1", "--quiet", "--no-planner-limit"]


def _runs(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.is_dir() and not p.is_symlink() and p.name != "cache")


# -- compare: a first-class subcommand ------------------------------------------------------------


def test_compare_help_shows_every_option_and_its_default(ehw):
    import cosim.cli.main

    cosim.cli.main.build_parser()
    sub = cosim.cli.main._SUBPARSERS["compare"]
    for action in sub._actions:
        if action.option_strings and action.dest != "help":
            assert action.help, action.dest
    text = " ".join(sub.format_help().split())
    for flag in ("--seeds N", "--first-seed FIRST", "--out DIR", "--resume", "--force", "--quiet",
                 "--config FILE", "--limit-seeds ROW=N", "--cluster", "--cache DIR", "--fresh", "--jobs J"):
        assert flag in text, flag
    assert "(default: 5)" in text and "(default: results/compare/cache)" in text


@pytest.mark.parametrize("args, words", [
    (["--seeds", "0"], ["--seeds", "0"]),
    (["--first-seed", "-1"], ["--first-seed", "-1"]),
    (["--jobs", "0"], ["--jobs"]),
    (["--methods", "baseline,sarsa"], ["--methods", "sarsa"]),
    (["--methods", ","], ["--methods"]),
    (["--shaping", "dense"], ["--shaping", "dense"]),
    (["--limit-seeds", "sarsa=1"], ["--limit-seeds", "sarsa=1"]),
    (["--limit-seeds", "offline=-1"], ["--limit-seeds", "offline=-1"]),
    (["--limit-seeds", "q-learning/dense=2"], ["--limit-seeds", "q-learning/dense"]),
    (["--limit-seeds", "offline"], ["--limit-seeds"]),
    (["--online", "loop_radius_mm=nan"], ["--online", "loop_radius_mm", "finite"]),
    (["--online", "loop_radius_mm=inf"], ["--online", "finite"]),
    (["--online", "population=-5"], ["--online", "population"]),
    (["--online", "no_such_field=1"], ["--online", "KEY=VALUE"]),
    (["--online", "escape=maybe"], ["--online", "escape"]),
    (["--max-interactions", "0"], ["--max-interactions"]),
    (["--generations-cap", "-2"], ["--generations-cap"]),
    (["--blind-bit", "9", "--blind-after-target", "1"], ["--blind-bit", "9"]),
    (["--blind-bit", "1"], ["--blind-bit", "--blind-after-target"]),
    (["--blind-bit", "1", "--blind-after-target", "0"], ["--blind-after-target", "0"]),
    (["--adaptation-only"], ["--adaptation-only", "--blind-bit"]),
    (["--resume", "--force"], ["--resume", "--force"]),
    (["--seeds", "nan"], ["--seeds", "'nan'"]),
    (["--reuse"], ["--reuse", "latest"]),
    (["--reuse", "nowhere"], ["--reuse", "nowhere/compare.json"]),
    (["--render", "nowhere.json"], ["--render", "nowhere.json"]),
    (["--resume"], ["--resume", "latest"]),
])
def test_compare_inputs_are_checked_before_any_work(ehw, tmp_path, args, words):
    t0 = time.perf_counter()
    one_error(*ehw("compare", *args)[::2], *words)
    assert time.perf_counter() - t0 < 5
    assert not (tmp_path / "results").exists()


def test_compare_files_are_checked_first(ehw, tmp_path):
    (tmp_path / "broken.json").write_text("{not json")
    one_error(*ehw("compare", *SMALL, "--arena", "broken.json")[::2], "broken.json", "not valid JSON")
    one_error(*ehw("compare", *SMALL, "--arena", _arena_file(tmp_path, ball_radius_mm=-1))[::2], "ball_radius_mm")
    (tmp_path / "a_file").write_text("x")
    one_error(*ehw("compare", *SMALL, "--cache", "a_file")[::2], "--cache", "a_file", "is a file")
    one_error(*ehw("compare", *SMALL, "--out", "a_file")[::2], "a_file", "is a file")
    (tmp_path / "half").mkdir()
    (tmp_path / "half/compare.json").write_text("[]")
    one_error(*ehw("compare", "--adaptation-only", "--blind-bit", "0", "--blind-after-target", "2",
                    "--out", "half")[::2], "half/compare.json", "not a compare report")
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("text, words", [
    ("seedz = 2\n", ["'seedz'", "did you mean 'seeds'"]),
    ('seeds = "2"\n', ["'seeds'", "an integer"]),
    ("limit_seeds = 3\n", ["'limit_seeds'", "a list"]),
    ("limit_seeds = [3]\n", ["'limit_seeds' item 0", "a string"]),
    ('methods = "sarsa"\n', ["--methods", "sarsa"]),
    ('distance = "backward"\n', ["'distance'", "'forward'"]),
    ('out = "x"\n', ["'out'", "not a run option"]),
])
def test_compare_config_file_errors_name_the_key(ehw, tmp_path, text, words):
    (tmp_path / "bad.toml").write_text(text)
    one_error(*ehw("compare", "--config", "bad.toml", "--seeds", "1", "--jobs", "1", "--quiet")[::2], *words)
    assert not (tmp_path / "results").exists()


def test_compare_runs_keep_both_and_rerun_from_their_config(ehw, tmp_path):
    """Two comparisons: two folders, `latest` at the second, the shared cache used by both;
    an --out holding a comparison refused; its config.toml / compare.json re-run it."""
    root = tmp_path / "results/compare"
    assert ehw("compare", *SMALL)[0] == 0
    first = (root / LATEST).resolve()
    status, out, _ = ehw("compare", *SMALL, "--first-seed", "2", "--limit-seeds", "q-learning=1")
    assert status == 0
    second = (root / LATEST).resolve()
    assert first != second and _runs(root) == sorted([first, second])
    assert second.name.endswith("-seeds2-2") and {p.name for p in second.iterdir()} >= {
        "compare.json", "compare.md", "compare.png", "config.toml"}
    assert json.loads((first / "compare.json").read_text())["seeds"] == [1]
    assert (root / "cache").is_dir()
    before = (second / "compare.json").read_bytes()
    status, out, err = ehw("compare", *SMALL, "--out", second)
    one_error(status, err, "already holds a run", "--force")
    assert (second / "compare.json").read_bytes() == before
    # The run's config.toml and its compare.json re-run it (from the cache: the same table).
    for source in (second / "config.toml", second / "compare.json"):
        out_dir = tmp_path / f"again_{source.suffix[1:]}"
        assert ehw("compare", "--config", source, "--out", out_dir)[0] == 0
        again = json.loads((out_dir / "compare.json").read_text())
        assert again["per_seed"] == json.loads(before)["per_seed"]
        assert again["config"] == json.loads(before)["config"]


def test_compare_resume_and_force(ehw, tmp_path):
    assert ehw("compare", *SMALL, "--out", "run")[0] == 0
    # --resume continues the comparison under its stored options; a flag that changes it is refused.
    assert ehw("compare", "--resume", "--out", "run", "--jobs", "2", "--quiet")[0] == 0
    one_error(*ehw("compare", "--resume", "--out", "run", "--seeds", "3")[::2], "--seeds 3", "stored 1")
    assert ehw("compare", *SMALL, "--methods", "baseline", "--out", "run", "--force")[0] == 0
    report = json.loads((tmp_path / "run/compare.json").read_text())
    assert set(report["per_seed"]) == {"baseline"}
    # --force replaces one comparison, never a tree of runs.
    one_error(*ehw("compare", *SMALL, "--out", ".", "--force")[::2], "holds other runs")
    assert (tmp_path / "run/compare.json").exists()


def test_an_interrupted_comparison_resumes_and_a_refused_one_leaves_nothing(ehw, tmp_path, monkeypatch):
    import cosim.compare.sweep

    root = tmp_path / "results/compare"
    assert ehw("compare", *SMALL)[0] == 0
    done = (root / LATEST).resolve()

    def unreachable(*args, **kwargs):
        raise ConnectionError("cannot reach the Dask scheduler at 'tcp://nowhere:1' (a test)")

    real_executor, real = cosim.compare.sweep.executor, cosim.compare.sweep.run_sweep
    monkeypatch.setattr(cosim.compare.sweep, "executor", unreachable)
    one_error(*ehw("compare", *SMALL, "--seeds", "2", "--cluster", "tcp://nowhere:1")[::2], "--cluster", "nowhere")
    assert _runs(root) == [done] and (root / LATEST).resolve() == done
    monkeypatch.setattr(cosim.compare.sweep, "executor", real_executor)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cosim.compare.sweep, "run_sweep", interrupted)
    assert ehw("compare", *SMALL, "--seeds", "2")[0] == 130
    stopped = (root / LATEST).resolve()
    assert stopped != done and (stopped / "config.toml").is_file() and not (stopped / "compare.json").exists()
    monkeypatch.setattr(cosim.compare.sweep, "run_sweep", real)
    assert ehw("compare", "--resume", "--quiet")[0] == 0  # the interrupted one, under its config
    assert json.loads((stopped / "compare.json").read_text())["seeds"] == [1, 2]


def test_compare_reuse_and_render_read_an_earlier_comparison(ehw, tmp_path):
    assert ehw("compare", *SMALL, "--out", "first")[0] == 0
    assert ehw("compare", *SMALL, "--methods", "baseline", "--reuse", "first", "--out", "second")[0] == 0
    report = json.loads((tmp_path / "second/compare.json").read_text())
    assert set(report["per_seed"]) == {"baseline", "q-learning/shaped"}
    (tmp_path / "second/compare.md").unlink()
    assert ehw("compare", "--render", "second/compare.json")[0] == 0
    assert "reactive baseline" in (tmp_path / "second/compare.md").read_text()


# -- baseline, arena, bench: run folders ------------------------------------------------------------


def test_baseline_runs_keep_both_and_out_is_refused(ehw, tmp_path):
    root = tmp_path / "results/baseline"
    assert ehw("baseline", "--arena", "empty", "--seeds", "1")[0] == 0
    first = (root / LATEST).resolve()
    assert ehw("baseline", "--arena", "empty", "--seeds", "0")[0] == 0
    second = (root / LATEST).resolve()
    assert first != second and _runs(root) == sorted([first, second])
    assert first.name.endswith("-seeds0-0") and second.name.endswith("-noise-free")
    assert json.loads((first / "baseline.json").read_text())["noisy"][0]["seed"] == 0
    assert json.loads((second / "baseline.json").read_text())["noisy"] == []
    before = (second / "baseline.json").read_bytes()
    one_error(*ehw("baseline", "--arena", "empty", "--out", second)[::2], "already holds a run", "--force")
    assert (second / "baseline.json").read_bytes() == before
    # Its config.toml re-runs it; --force replaces it.
    assert ehw("baseline", "--config", first / "config.toml", "--out", "again")[0] == 0
    assert json.loads((tmp_path / "again/baseline.json").read_text())["noisy"] == \
        json.loads((first / "baseline.json").read_text())["noisy"]
    assert ehw("baseline", "--arena", "empty", "--seeds", "0", "--out", "again", "--force")[0] == 0
    one_error(*ehw("baseline", "--first-seed", "-1")[::2], "--first-seed", "-1")
    one_error(*ehw("baseline", "--out", "results", "--force")[::2], "holds other runs")


def test_arena_runs_keep_both_and_out_is_refused(ehw, tmp_path):
    root = tmp_path / "results/arena"
    assert ehw("arena", "--arena", "empty")[0] == 0
    time.sleep(1.1)
    assert ehw("arena", "--arena", "one_obstacle")[0] == 0
    runs = _runs(root)
    assert len(runs) == 2 and (root / LATEST).resolve() == runs[-1]
    assert [p.name for p in runs[0].glob("*.png")] == ["arena_empty.png"]
    assert [p.name for p in runs[1].glob("*.png")] == ["arena_one_obstacle.png"]
    assert ehw("arena", "--arena", "empty", "--out", "pics")[0] == 0
    one_error(*ehw("arena", "--arena", "one_obstacle", "--out", "pics")[::2], "'pics'", "already holds a run")
    assert ehw("arena", "--arena", "one_obstacle", "--out", "pics", "--force")[0] == 0
    assert [p.name for p in (tmp_path / "pics").glob("*.png")] == ["arena_one_obstacle.png"]


def test_bench_keeps_every_run_and_merges_into_results_bench_json(ehw, tmp_path, monkeypatch):
    import benchmarks.__main__ as bench

    monkeypatch.setattr(bench, "_names", lambda: ["bench_a", "bench_b"])
    figures = {"bench_a": {"a": 1}, "bench_b": {"b": 2}}
    monkeypatch.setattr(bench, "_load",
                        lambda name: type("M", (), {"run": staticmethod(lambda: dict(figures[name]))}))
    root = tmp_path / "results/bench"
    assert ehw("bench", "bench_a")[0] == 0
    time.sleep(1.1)
    figures["bench_a"] = {"a": 3}
    assert ehw("bench", "bench_b")[0] == 0
    assert ehw("bench", "bench_a", "--out", "mine")[0] == 0
    runs = _runs(root)
    assert len(runs) == 2 and (root / LATEST).resolve() == runs[-1]
    assert json.loads((runs[0] / "bench.json").read_text())["a"] == 1
    assert "a" not in json.loads((runs[1] / "bench.json").read_text())
    merged = json.loads((tmp_path / "results/bench.json").read_text())
    assert merged["a"] == 3 and merged["b"] == 2  # the newest figure of every module
    one_error(*ehw("bench", "bench_a", "--out", "mine")[::2], "'mine'", "already holds a run")
    one_error(*ehw("bench", "--out", "results/bench.json")[::2], "--out", "--figures")
    one_error(*ehw("bench", "nope")[::2], "nope")
    (tmp_path / "list.json").write_text("[1]")
    one_error(*ehw("bench", "--figures", "list.json")[::2], "list.json", "no JSON object")


def test_two_merges_at_once_both_land(tmp_path):
    from base.files import merge_json

    path = tmp_path / "bench.json"
    threads = [threading.Thread(target=merge_json, args=(path, {f"k{i}": i})) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert json.loads(path.read_text()) == {f"k{i}": i for i in range(8)}


# -- the new loaders: any input loads or raises the project's error type --------------------------


@settings(max_examples=150)
@given(value=st.recursive(st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=5)),
                          lambda inner: st.lists(inner, max_size=3), max_leaves=6))
def test_list_option_values_load_or_raise(value):
    from base.config_file import ConfigFileError, check_value

    try:
        got = check_value(value, list[str], "key 'limit_seeds'")
    except ConfigFileError:
        return
    assert isinstance(got, list) and all(isinstance(v, str) for v in got)


@settings(max_examples=150, deadline=None)
@given(text=st.one_of(st.text(max_size=40), st.recursive(
    st.one_of(st.none(), st.integers(), st.text(max_size=4)),
    lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=4), inner, max_size=3)),
    max_leaves=8).map(lambda v: json.dumps({"per_seed": v}))))
def test_compare_report_loader_loads_or_raises(tmp_path_factory, text):
    from base.errors import UserError
    from cosim.compare.options import read_report

    path = tmp_path_factory.mktemp("cmp") / "compare.json"
    path.write_text(text)
    try:
        report = read_report(path, "--reuse")
    except UserError:
        return
    assert all(isinstance(s, int) for per in report["per_seed"].values() for s in per)


@settings(max_examples=80, deadline=None)
@given(items=st.lists(st.text(alphabet="abcdefghilnoqrsuw/-=,0123456789 ", max_size=20), max_size=3))
def test_limit_seeds_parse_or_raise(items):
    from base.errors import UserError
    from cosim.compare.options import limits_of

    try:
        limits = limits_of(items)
    except UserError:
        return
    assert all(isinstance(n, int) and n >= 0 for n in limits.values())


@settings(max_examples=100, deadline=None)
@given(text=st.one_of(st.text(max_size=30), st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.text(max_size=4)),
    lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=4), inner, max_size=3)),
    max_leaves=6).map(json.dumps)))
def test_bench_figures_loader_loads_or_raises(tmp_path_factory, text):
    from base.errors import UserError
    from base.files import merge_json

    path = tmp_path_factory.mktemp("bench") / "bench.json"
    path.write_bytes(text.encode())
    try:
        merged = merge_json(path, {"new_key": 1})
    except UserError:
        assert path.read_bytes() == text.encode()  # a file that is not figures is left as it was (bytes: read_text would turn a lone '\r' into '\n')
        return
    assert merged["new_key"] == 1 and json.loads(path.read_text()) == merged
