"""Property tests of the loaders (issue 15): for any mutated input, the arena, config-file and
checkpoint loaders either give a valid object or raise the project's error type (a
``base.errors.UserError``: one ``error:`` line at the command line), never another exception."""

from __future__ import annotations

import copy
import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from base.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from base.config_file import ConfigFileError, field_types, load_config_file, to_toml
from base.errors import UserError
from sim_world.arena import ARENA_DIR, Arena, ArenaError, arena_from_dict

EMPTY = json.loads((ARENA_DIR / "empty.json").read_text())
DEFAULT = json.loads((ARENA_DIR / "default.json").read_text())

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.integers(),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
json_values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                            st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                           max_leaves=10)


def _paths(value, prefix=()):
    """Every path into a JSON structure (keys and list indices)."""
    yield prefix
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _paths(v, prefix + (i,))


@st.composite
def mutated(draw, base):
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "delete", "nudge"]))
        if action == "delete":
            del parent[path[-1]]
        elif action == "nudge" and isinstance(parent[path[-1]], (int, float)) and not isinstance(parent[path[-1]], bool):
            parent[path[-1]] = parent[path[-1]] + draw(st.sampled_from([-1000, -100, -1, 1, 100, 1000, 10**9]))
        else:
            parent[path[-1]] = draw(json_values)
    return data


@settings(max_examples=80, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.one_of(mutated(EMPTY), mutated(DEFAULT)))
def test_arena_loader_loads_or_raises_arena_error(data):
    try:
        arena = arena_from_dict(data)
    except ArenaError:
        return
    assert isinstance(arena, Arena) and len(arena.positions) == 64


def _online_types():
    from cosim.cli.commands import SIM_RUN_OPTIONS
    from cosim.online.run import OnlineConfig

    return {**field_types(OnlineConfig), **SIM_RUN_OPTIONS}


ONLINE_TYPES = _online_types()
VALID_TOML = to_toml({"backend": "reference", "seed": 3, "population": 20, "arena": "empty",
                      "loop_radius_mm": 80.0, "escape": True, "blind_bit": None})


@settings(max_examples=150)
@given(raw=st.dictionaries(st.one_of(st.sampled_from(sorted(ONLINE_TYPES)), st.text(max_size=10)),
                           st.one_of(scalars, st.lists(st.integers(), max_size=2)), max_size=5))
def test_config_loader_loads_or_raises_config_error(tmp_path_factory, raw):
    """Any key/value mapping: the checked values, or a ConfigFileError; what loads gives the
    run's OnlineConfig (as ``ehw sim --config`` builds it), or a UserError naming the field."""
    import cosim.cli.main
    from cosim.cli.commands import online_config
    from cosim.online.run import OnlineConfig

    path = tmp_path_factory.mktemp("cfg") / "run.json"
    path.write_text(json.dumps({"config": raw}))
    try:
        values = load_config_file(path, ONLINE_TYPES)
    except ConfigFileError:
        return
    assert set(values) <= set(ONLINE_TYPES)
    args = cosim.cli.main.build_parser().parse_args(["sim"])
    fields = {k: v for k, v in values.items() if k in field_types(OnlineConfig)}
    try:
        config = online_config(args, fields)
    except UserError:
        return
    assert isinstance(config, OnlineConfig)
    assert all(getattr(config, k) == v for k, v in fields.items())


@settings(max_examples=150)
@given(position=st.integers(0, len(VALID_TOML) - 1), new=st.binary(min_size=0, max_size=3))
def test_config_file_bytes_mutated_load_or_raise(tmp_path_factory, position, new):
    text = VALID_TOML.encode()
    path = tmp_path_factory.mktemp("cfg") / "run.toml"
    path.write_bytes(text[:position] + new + text[position + 1:])
    try:
        values = load_config_file(path, ONLINE_TYPES)
    except ConfigFileError:
        return
    assert set(values) <= set(ONLINE_TYPES)


@settings(max_examples=150)
@given(position=st.integers(0, 10**6), new=st.binary(min_size=0, max_size=2), cut=st.booleans())
def test_checkpoint_loader_refuses_any_change(tmp_path_factory, position, new, cut):
    """A byte changed, inserted, deleted or the file cut: CheckpointError, or (a change JSON does
    not see, e.g. in white space) exactly the stored config and state."""
    path = tmp_path_factory.mktemp("ck") / "checkpoint.json"
    config, state = {"seed": 1, "population": 20}, {"generations": 7, "phases": [{"reason": "crash"}]}
    save_checkpoint(path, "online", config, state)
    data = path.read_bytes()
    position %= len(data)
    data = data[:position] if cut else data[:position] + new + data[position + 1:]
    path.write_bytes(data)
    try:
        got = read_checkpoint(path, "online")
    except CheckpointError:
        return
    assert got == (config, state)
