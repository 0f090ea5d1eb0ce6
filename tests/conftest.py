"""Shared test settings: hypothesis profile, repository paths."""

import os
from pathlib import Path

from hypothesis import settings

REPO_ROOT = Path(__file__).resolve().parent.parent

settings.register_profile("ci", deadline=None, max_examples=200, derandomize=True)
settings.register_profile("dev", deadline=None, max_examples=100)
settings.load_profile("ci" if os.environ.get("CI") else "dev")
