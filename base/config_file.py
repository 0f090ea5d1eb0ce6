"""Run options from a file: ``--config run.toml`` (or a run's ``summary.json``).

A config file is flat TOML, one key per run option, named as the fields of the command's config
dataclass (``cosim.online.run.OnlineConfig`` for ``ehw sim``: ``seed``, ``population``,
``n_targets``, ``distance_rule``, ...) or as its run options (``backend``, ``simulator``, ...)::

    # run.toml
    backend = "reference"
    seed = 3
    population = 200
    loop_window = 150

Flags on the command line override the file; the file overrides the defaults. An unknown key or
a value of the wrong type (or NaN / infinity) is a :class:`ConfigFileError` naming the file and
the key. A run writes its complete config as ``config.toml`` beside its summary
(:func:`to_toml`), and a ``summary.json`` is accepted too (its ``config`` and ``backend``), so
any run can be re-run from its results: ``ehw sim --config results/.../config.toml``.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import tomllib
import types
import typing
from pathlib import Path

from base.errors import UserError


class ConfigFileError(UserError):
    """A config file that cannot be used; the message names the file and the key."""


def field_types(cls) -> dict[str, object]:
    """``{name: type}`` of a config dataclass (annotations resolved)."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)}


def _allowed(tp) -> tuple[tuple[type, ...], bool]:
    """(the plain types a value may have, whether None is allowed)."""
    if isinstance(tp, types.UnionType) or typing.get_origin(tp) is typing.Union:
        args = typing.get_args(tp)
        plain = tuple(a for a in args if a is not type(None))
        return plain, len(plain) < len(args)
    return (tp,), False


def check_value(value, tp, what: str):
    """``value`` if it has type ``tp`` (an int for a float is fine; ``list[str]``: a list of
    strings, or one string), else a ConfigFileError."""
    if typing.get_origin(tp) is list:
        (item,) = typing.get_args(tp)
        items = [value] if isinstance(value, str) else value
        if not isinstance(items, list):
            raise ConfigFileError(f"{what} must be a list, got {type(value).__name__} {value!r}")
        return [check_value(v, item, f"{what} item {n}") for n, v in enumerate(items)]
    plain, nullable = _allowed(tp)
    if value is None:
        if nullable:
            return None
        raise ConfigFileError(f"{what} must be {_names(plain)}, got nothing (null)")
    for t in plain:
        if t is bool and isinstance(value, bool):
            return value
        if t is int and isinstance(value, int) and not isinstance(value, bool):
            return value
        if t is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ConfigFileError(f"{what} must be a finite number, got {value!r}")
            return float(value)
        if t is str and isinstance(value, str):
            return value
    raise ConfigFileError(f"{what} must be {_names(plain)}, got {type(value).__name__} {value!r}")


def _names(plain) -> str:
    return " or ".join({bool: "true/false", int: "an integer", float: "a number",
                        str: "a string"}.get(t, getattr(t, "__name__", str(t))) for t in plain)


def read_config_file(path) -> dict:
    """The raw key/value mapping of a TOML config file or of a run's summary.json."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigFileError(f"cannot read config file {str(path)!r}: {exc.strerror}") from None
    if path.suffix == ".json":
        try:
            summary = json.loads(data)
        except (ValueError, UnicodeDecodeError) as exc:
            raise ConfigFileError(f"config file {str(path)!r} is not valid JSON: {exc}") from None
        if not isinstance(summary, dict) or not isinstance(summary.get("config"), dict):
            raise ConfigFileError(f"config file {str(path)!r}: a .json config is a run's summary, "
                                  "with a 'config' object")
        values = dict(summary["config"])
        values.update(summary.get("run_options") or {})
        if "backend" in summary and "backend" not in values:
            values["backend"] = summary["backend"]
        return values
    try:
        return tomllib.loads(data.decode())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigFileError(f"config file {str(path)!r} is not valid TOML: {exc}") from None


def load_config_file(path, types_of: dict[str, object], choices: dict[str, tuple] | None = None) -> dict:
    """The checked values of the config file ``path``: every key must be in ``types_of``
    (``{key: type}``) with a value of that type (and in ``choices[key]`` where given)."""
    raw = read_config_file(path)
    out = {}
    for key, value in raw.items():
        what = f"config file {str(path)!r}: key {key!r}"
        if key not in types_of:
            near = difflib.get_close_matches(key.replace("-", "_"), list(types_of), n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise ConfigFileError(f"{what} is not a run option{hint}; known keys: {', '.join(sorted(types_of))}")
        if isinstance(value, dict):
            raise ConfigFileError(f"{what}: tables are not used, write the keys at the top level")
        value = check_value(value, types_of[key], what)
        if choices and key in choices and value not in choices[key]:
            raise ConfigFileError(f"{what} must be one of {', '.join(map(repr, choices[key]))}, got {value!r}")
        out[key] = value
    return out


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"a config value must be finite, got {value!r}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")


def to_toml(values: dict, header: str = "") -> str:
    """Flat TOML of ``values`` (None values are left out: absent means the default None)."""
    lines = [f"# {line}" for line in header.splitlines()]
    lines += [f"{key} = {_toml_value(value)}" for key, value in values.items() if value is not None]
    return "\n".join(lines) + "\n"
