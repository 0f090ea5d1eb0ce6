"""World model of SPEC section 7: the normative update rule, the state set, save and load."""

import json

import pytest
from hypothesis import given, strategies as st

from ga.world_model import FORMAT_TAG, FORMAT_VERSION, WorldModel, WorldModelError

observations = st.lists(
    st.tuples(st.integers(0, 255), st.integers(0, 7), st.integers(0, 255), st.booleans()), max_size=60
)


def test_empty_model():
    model = WorldModel()
    assert model.n_states == 0 and model.n_transitions == 0
    assert model.states.tolist() == [] and model.entries().shape == (0, 4)


def test_most_recent_outcome_overwrites():
    model = WorldModel()
    assert model.observe(3, 1, 7, False)
    assert model.observe(3, 1, 9, False)
    assert (model.valid[3, 1], model.crash[3, 1], model.next_state[3, 1]) == (True, False, 9)
    assert model.states.tolist() == [3, 7, 9]  # S keeps every state the robot has been in
    assert model.n_transitions == 1
    assert not model.observe(3, 1, 9, False)  # nothing new


def test_crash_entry_is_never_overwritten():
    model = WorldModel()
    model.observe(5, 0, 6, False)
    assert model.observe(5, 0, 5, True)  # a crash overwrites a free entry
    assert (model.crash[5, 0], model.next_state[5, 0]) == (True, 5)
    assert not model.observe(5, 0, 6, False)  # ... but nothing overwrites a crash
    assert (model.valid[5, 0], model.crash[5, 0], model.next_state[5, 0]) == (True, True, 5)
    assert model.observe(5, 0, 11, False)  # a new state still joins S
    assert model.crash[5, 0] and model.in_set[11]


def test_crash_records_the_from_state():
    model = WorldModel()
    model.observe(17, 4, 19, True)  # noise: the robot, put back, sees 19
    assert model.next_state[17, 4] == 17 and model.crash[17, 4]
    assert model.states.tolist() == [17, 19]


def test_visit_adds_initial_state():
    model = WorldModel()
    assert model.visit(42) and not model.visit(42)
    assert model.states.tolist() == [42] and model.n_transitions == 0


@pytest.mark.parametrize("args", [(256, 0, 0, False), (-1, 0, 0, False), (0, 8, 0, False),
                                  (0, 0, 300, False), (0, True, 0, False), (1.5, 0, 0, False)])
def test_bad_observation_is_rejected(args):
    with pytest.raises(WorldModelError):
        WorldModel().observe(*args)


@given(observations)
def test_invariants_and_reference_rule(obs):
    model = WorldModel()
    table = {}
    seen = set()
    for s, a, s2, c in obs:
        model.observe(s, a, s2, c)
        seen |= {s, s2}
        if (s, a) in table and table[s, a][1]:
            continue
        table[s, a] = (s if c else s2, c)
    assert model.states.tolist() == sorted(seen)
    assert {(int(s), int(a)): (int(n), bool(c)) for s, a, n, c in model.entries()} == table
    valid = model.valid
    assert model.in_set[model.next_state[valid]].all()  # next states are in S
    assert not (model.crash & ~valid).any()


@given(observations)
def test_save_load_round_trip(tmp_path_factory, obs):
    model = WorldModel()
    for o in obs:
        model.observe(*o)
    path = model.save(tmp_path_factory.mktemp("wm") / "model.json")
    loaded = WorldModel.load(path)
    assert loaded == model
    copy = model.copy()
    copy.observe(1, 1, 2, True)
    copy.visit(200)
    assert model == loaded  # the copy shares no array with the original
    assert copy.in_set[200] and copy.crash[1, 1]


def _write(path, data):
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


GOOD = {"format": FORMAT_TAG, "version": FORMAT_VERSION, "states": [1, 2], "transitions": [[1, 0, 2, 0]]}


@pytest.mark.parametrize("data", [
    "{not json",
    "",
    [1, 2],
    {**GOOD, "format": "something-else"},
    {**GOOD, "version": FORMAT_VERSION + 1},
    {**GOOD, "states": [1, 1, 2]},
    {**GOOD, "states": [1, 256]},
    {**GOOD, "transitions": [[1, 0, 3, 0]]},  # next state outside S
    {**GOOD, "transitions": [[1, 0, 2, 0], [1, 0, 2, 0]]},
    {**GOOD, "transitions": [[1, 9, 2, 0]]},
    {**GOOD, "transitions": [[1, 0, 2, 2]]},
    {**GOOD, "transitions": [[1, 0, 2, 1]]},  # a crash entry must record next = state
    {**GOOD, "transitions": [[1, 0, 2]]},
    {"format": FORMAT_TAG, "version": FORMAT_VERSION},
])
def test_corrupt_file_is_a_clear_error(tmp_path, data):
    path = _write(tmp_path / "bad.json", data)
    with pytest.raises(WorldModelError, match="bad.json"):
        WorldModel.load(path)


def test_good_file_loads_and_missing_file_fails(tmp_path):
    model = WorldModel.load(_write(tmp_path / "good.json", GOOD))
    assert model.states.tolist() == [1, 2] and model.next_state[1, 0] == 2
    with pytest.raises(WorldModelError, match="missing"):
        WorldModel.load(tmp_path / "missing.json")
