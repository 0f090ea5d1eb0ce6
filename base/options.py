"""What every command line of the project shares: the flags every run has, spelled the same
everywhere; help that shows each default; run options from a config file (``base.config_file``)
applied to a parser, and a run's complete config written beside its results.

Imports only ``base``: ``cosim.cli``, ``benchmarks`` and ``sim_world``'s commands may use it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from base.config_file import load_config_file, to_toml
from base.files import atomic_write_text

PROG = "ehw"


# Options that only say how a command runs, never what it computes: not recorded in config.toml.
NOT_CONFIG = {"out", "resume", "force", "config", "quiet", "no_progress", "command", "help"}


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Every option's default after its help (unless the help already says it)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "%(default)" in text or "(default" in text or action.default in (None, argparse.SUPPRESS, False) \
                or not action.option_strings or isinstance(action.default, list) and not action.default:
            return text
        return f"{text} (default: %(default)s)".lstrip()


def add_common(p, *, seed: bool = True, out_help: str = "", resume: bool = True,
                force: bool = True, quiet: bool = True, config: bool = True) -> None:
    """The flags every run shares, spelled the same in every subcommand."""
    if seed:
        p.add_argument("--seed", type=int, default=1, help="the run's seed")
    if out_help:
        p.add_argument("--out", type=Path, default=None, metavar="DIR", help=out_help)
    if resume:
        p.add_argument("--resume", action="store_true",
                       help="continue the run in --out (without --out: the one 'latest' points at) "
                            "from its checkpoint, under the config stored there")
    if force:
        p.add_argument("--force", action="store_true",
                       help="replace the run --out holds (its result files are deleted first)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress bar")
    if config:
        p.add_argument("--config", type=Path, default=None, metavar="FILE",
                       help="run options from a TOML file (or a run's config.toml / summary.json); "
                            "flags override it")


def add_field_options(p, defaults, helps: dict, prefix: str = "", extra: dict | None = None) -> None:
    """One option per field of the dataclass instance ``defaults`` that ``helps`` names, in its
    order: ``--<prefix><field>`` (``_`` as ``-``), dest ``<prefix><field>``, its default the field's
    value, its type the default's (a bool is ``--x/--no-x``); ``extra`` adds keywords per field
    (``choices``, ``metavar``)."""
    for name, text in helps.items():
        value = getattr(defaults, name)
        keywords = {"default": value, "help": text, **(extra or {}).get(name, {})}
        if isinstance(value, bool):
            keywords["action"] = argparse.BooleanOptionalAction
        else:
            keywords.setdefault("type", type(value))
        p.add_argument("--" + (prefix + name).replace("_", "-"), **keywords)


def fill_help(p, note: str) -> None:
    """Options without a help text get one (``--help`` then lists every option and its default)."""
    for action in p._actions:
        if action.help is None and action.option_strings:
            action.help = note.format(dest=action.dest)


def action_type(action):
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse.BooleanOptionalAction)):
        return bool
    if isinstance(action, argparse._AppendAction):  # a repeatable option: a list in the file
        return list[action.type if action.type in (int, float) else str]
    if action.type in (int, float, str):
        return action.type | None if action.default is None else action.type
    if action.type is Path or action.type is None:
        return str | None if action.default is None else str
    return str


def option_keys(parser, exclude=()) -> dict[str, argparse.Action]:
    return {a.dest: a for a in parser._actions
            if a.option_strings and a.dest not in NOT_CONFIG and a.dest not in exclude
            and not isinstance(a, argparse._HelpAction)}


def apply_config_file(sub, path, extra_types: dict | None = None, dest_of: dict | None = None) -> dict:
    """Set ``sub``'s defaults from the config file ``path``; return the keys that have no option
    (``extra_types`` lists those allowed; ``dest_of`` maps a key to its option's dest)."""
    actions = option_keys(sub)
    dest_of = dest_of or {}
    key_of = {dest: key for key, dest in dest_of.items()}
    types_of = {key_of.get(dest, dest): action_type(action) for dest, action in actions.items()}
    types_of.update(extra_types or {})  # a config dataclass's own field types come first
    choices = {key: tuple(actions[dest_of.get(key, key)].choices) for key in types_of
               if dest_of.get(key, key) in actions and actions[dest_of.get(key, key)].choices}
    values = load_config_file(path, types_of, choices)
    defaults, extras = {}, {}
    for key, value in values.items():
        dest = dest_of.get(key, key)
        if dest in actions:
            defaults[dest] = str(value) if actions[dest].type is Path and value is not None else value
        else:
            extras[key] = value
    sub.set_defaults(**defaults)
    return extras


def resume_config(args, root: Path) -> Path | None:
    """With ``--resume`` and no ``--config``: the ``config.toml`` of the run being resumed (the
    ``--out`` folder, else the one ``root/latest`` points at), whose options become the defaults
    (flags over them); None where there is none."""
    from base.runs import read_latest

    if not getattr(args, "resume", False) or getattr(args, "config", None) is not None:
        return None
    folder = args.out if args.out is not None else read_latest(root)
    path = None if folder is None else Path(folder) / "config.toml"
    return path if path is not None and path.is_file() else None


def write_config(folder: Path, run_options: dict, config: dict, what: str) -> Path:
    header = (f"The complete config of this {what} run, as --config reads it back:\n"
              f"  {PROG} {what} --config {folder / 'config.toml'} --out NEW_FOLDER")
    return atomic_write_text(folder / "config.toml", to_toml({**run_options, **config}, header))
