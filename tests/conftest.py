"""Shared test settings: hypothesis profile, repository paths; the ``ehw`` fixture (the console
script in a fresh folder) and :func:`one_error` (what a user error looks like)."""

import os
from pathlib import Path

import pytest
from hypothesis import settings

REPO_ROOT = Path(__file__).resolve().parent.parent

settings.register_profile("ci", deadline=None, max_examples=200, derandomize=True)
settings.register_profile("dev", deadline=None, max_examples=100)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture
def ehw(tmp_path, monkeypatch, capsys):
    """``ehw(*args) -> (status, stdout, stderr)`` with the working directory a fresh folder and
    none of the project's environment variables set."""
    from base import environ
    from cosim.cli.main import main as ehw_main

    monkeypatch.chdir(tmp_path)
    for name in environ.VARIABLES:
        monkeypatch.delenv(name, raising=False)

    def run(*args):
        capsys.readouterr()
        status = ehw_main([str(a) for a in args])
        out, err = capsys.readouterr()
        return status, out, err

    return run


def one_error(status, err, *words):
    """A user error: exit status 2 and one `error:` line naming the problem, no traceback."""
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])
