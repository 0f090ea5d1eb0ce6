"""Atomic checkpoints and their clear errors."""

import json

import pytest

from base.checkpoint import CheckpointError, load_checkpoint, save_checkpoint

CONFIG = {"seed": 1, "population": 20, "arena": "default", "rates": (0.1, 0.2)}


def test_round_trip(tmp_path):
    path = tmp_path / "sub" / "ck.json"
    save_checkpoint(path, "offline", CONFIG, {"generation": 3, "big": 2**127 + 1, "x": 0.1})
    state = load_checkpoint(path, "offline", CONFIG)
    assert state == {"generation": 3, "big": 2**127 + 1, "x": 0.1}
    assert [p.name for p in path.parent.iterdir()] == ["ck.json"]  # no temp file left


def test_overwrite_is_atomic_replace(tmp_path):
    path = tmp_path / "ck.json"
    save_checkpoint(path, "offline", CONFIG, {"generation": 1})
    with pytest.raises(ValueError):
        save_checkpoint(path, "offline", CONFIG, {"bad": float("nan")})  # fails before replacing
    assert load_checkpoint(path, "offline", CONFIG) == {"generation": 1}
    assert len(list(tmp_path.iterdir())) == 1


def test_missing_file(tmp_path):
    with pytest.raises(CheckpointError, match="cannot read"):
        load_checkpoint(tmp_path / "none.json", "offline", CONFIG)


@pytest.mark.parametrize("text", ["{not json", '{"format": 1}', "[1, 2]", ""])
def test_corrupt(tmp_path, text):
    path = tmp_path / "ck.json"
    path.write_text(text)
    with pytest.raises(CheckpointError, match="corrupt"):
        load_checkpoint(path, "offline", CONFIG)


def test_truncated_file_is_corrupt(tmp_path):
    path = tmp_path / "ck.json"
    save_checkpoint(path, "offline", CONFIG, {"generation": 1})
    path.write_text(path.read_text()[:-10])
    with pytest.raises(CheckpointError, match="corrupt"):
        load_checkpoint(path, "offline", CONFIG)


def test_wrong_kind(tmp_path):
    path = tmp_path / "ck.json"
    save_checkpoint(path, "online", CONFIG, {})
    with pytest.raises(CheckpointError, match="'online' checkpoint, not 'offline'"):
        load_checkpoint(path, "offline", CONFIG)


def test_wrong_format(tmp_path):
    path = tmp_path / "ck.json"
    save_checkpoint(path, "offline", CONFIG, {})
    payload = json.loads(path.read_text())
    payload["format"] = 99
    path.write_text(json.dumps(payload))
    with pytest.raises(CheckpointError, match="format version 99"):
        load_checkpoint(path, "offline", CONFIG)


def test_config_mismatch_names_keys(tmp_path):
    path = tmp_path / "ck.json"
    save_checkpoint(path, "offline", CONFIG, {})
    other = dict(CONFIG, seed=2, extra=True)
    with pytest.raises(CheckpointError) as info:
        load_checkpoint(path, "offline", other)
    msg = str(info.value)
    assert "seed: saved 1, now 2" in msg and "extra" in msg and "population" not in msg
