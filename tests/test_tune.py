"""``ehw tune`` (issue 36 part 2): an Optuna TPE study per method, seeded, in SQLite, resumable."""

from __future__ import annotations

import dataclasses
import json

import optuna
import pytest

from base.errors import UserError
from cosim.cli.main import main
from cosim.cli.tune import parse_seeds
from cosim.compare.run import make_tasks
from cosim.compare.tune import CAP, SPACES, incumbent, study_name, to_64, trial_tasks, tune
from peers.tabular import DEFAULTS, LearnerConfig


def test_seed_lists():
    assert parse_seeds("1001-1003") == [1001, 1002, 1003]
    assert parse_seeds("5,7, 9-10") == [5, 7, 9, 10]
    for bad in ("", "a-b", "3,3", "-1"):
        with pytest.raises(UserError, match="--seeds"):
            parse_seeds(bad)


def test_a_capped_lifetime_counts_at_the_cap():
    assert to_64({"target_interactions": list(range(1, 65))}) == 64
    assert to_64({"target_interactions": list(range(1, 40)), "interactions": CAP}) == CAP


def test_trial_tasks_are_the_comparisons_with_the_trials_settings():
    params = {"alpha": 0.3, "gamma": 0.9, "epsilon": 0.01, "q_init": 0.5, "planning_steps": 7, "kappa": 0.01}
    tasks = trial_tasks("dyna-q+", "shaped", params, [1001, 1002], "default", "out")
    plain = make_tasks(["dyna-q+"], [1001, 1002], arena="default", out="out", shapings=("shaped",))
    assert [t["seed"] for t in tasks] == [1001, 1002]
    assert tasks[0]["config"]["learner"] == dataclasses.asdict(dataclasses.replace(DEFAULTS["dyna-q+"], **params))
    assert {k: v for k, v in tasks[0]["config"].items() if k != "learner"} == \
        {k: v for k, v in plain[0]["config"].items() if k != "learner"}
    online = trial_tasks("online", "shaped", {"loop_window": 60}, [3], "default", "out")
    assert online[0]["config"]["online"]["loop_window"] == 60
    assert online[0]["config"]["online"]["range_noise"] == 0.10  # honest sensing, as compared


def test_every_space_gives_valid_settings():
    from cosim.online.config import OnlineConfig

    for method, space in SPACES.items():
        study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=1))
        trial = study.ask()
        params = space(trial)
        if method == "online":
            OnlineConfig(**params)
        elif method in DEFAULTS:
            dataclasses.replace(DEFAULTS[method], **params)
            LearnerConfig(**{**dataclasses.asdict(DEFAULTS[method]), **params})
        else:
            assert params and all(isinstance(v, float) for v in params.values())


def test_a_study_is_seeded_stored_and_resumed(tmp_path):
    kw = dict(jobs=1, progress=False, cache_root=tmp_path / "cache")
    first = tune("q-learning", [1001], 2, out=tmp_path / "a", **kw)
    assert first["finished_trials"] == 2 and (tmp_path / "a" / "q-learning-shaped.db").exists()
    assert json.loads((tmp_path / "a" / "q-learning-shaped.json").read_text()) == first
    assert first["best"]["median"] == min(t["median"] for t in first["trials"])
    # resumed: the two trials kept, one more run
    more = tune("q-learning", [1001], 3, out=tmp_path / "a", **kw)
    assert more["finished_trials"] == 3 and more["trials"][:2] == first["trials"]
    # another folder, the same sampler seed: the same trials (lifetimes from the cache)
    again = tune("q-learning", [1001], 2, out=tmp_path / "b", **kw)
    assert again["trials"] == first["trials"]
    other = tune("q-learning", [1001], 2, out=tmp_path / "c", sampler_seed=5, **kw)
    assert other["trials"][0]["params"] == first["trials"][0]["params"]  # the incumbent
    assert other["trials"][1]["params"] != first["trials"][1]["params"]


def test_every_study_starts_from_the_settings_compared_today(tmp_path):
    report = tune("q-learning", [1001], 1, out=tmp_path, jobs=1, progress=False, cache_root=tmp_path / "cache")
    from peers.tabular import TUNED

    shipped = dataclasses.asdict(TUNED[("q-learning", "shaped")])
    assert report["trials"][0]["params"] == {k: shipped[k] for k in ("alpha", "gamma", "epsilon", "q_init")}
    assert report["incumbent"]["trial"] == 0
    for method in SPACES:
        for shaping in ("shaped", "unshaped"):
            current = incumbent(method, shaping)
            trial = optuna.create_study().ask()
            SPACES[method](trial)
            assert current.keys() == trial.distributions.keys()
            for name, dist in trial.distributions.items():  # inside the searched range
                assert dist._contains(dist.to_internal_repr(current[name])), (method, name, current[name])
    from cosim.online.config import OnlineConfig

    assert incumbent("online", "shaped")["progress_weight"] == OnlineConfig().progress_weight


def test_an_interrupted_trial_runs_again_with_its_settings(tmp_path):
    storage = f"sqlite:///{tmp_path / 'q-learning-shaped.db'}"
    study = optuna.create_study(study_name=study_name("q-learning", "shaped", [1001]), storage=storage,
                                direction="minimize")
    cut = study.ask()
    params = SPACES["q-learning"](cut)
    study.tell(cut, state=optuna.trial.TrialState.FAIL)  # as a Ctrl-C in its objective leaves it
    report = tune("q-learning", [1001], 1, out=tmp_path, jobs=1, progress=False, cache_root=tmp_path / "cache")
    assert report["trials"][0]["params"] == params


def test_the_command_line_refuses_bad_requests(capsys):
    assert main(["tune", "nonsense", "--trials", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: METHOD must be one of")
    assert main(["tune", "q-learning", "--trials", "0"]) == 2
    assert main(["tune", "q-learning", "--trials", "1", "--seeds", "x"]) == 2
