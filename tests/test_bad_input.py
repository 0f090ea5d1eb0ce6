"""The last rough edges of bad input (issue 39, items 2-4): every environment variable the
project reads is checked in one place (``base.environ``), a blinding past the last target is
refused, a start that fails leaves its ``--out`` folder as it was, SIGTERM ends as SIGINT does."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from conftest import REPO_ROOT, one_error

from base import environ

TINY = ["--arena", "empty", "--targets", "1", "--population", "20", "--quiet", "--no-plots"]
# a value each variable cannot take
GARBAGE = {"EHW_SIM": "modelsim", "EHW_HDL_SAMPLE": "some", "WAVES": "maybe", "EHW_CLOCK_HZ": "-3",
           "EHW_FPGA_TARGET": "two words", "EHW_SYSTEM_P_MAX": "0", "EHW_PORT": " /dev/ttyUSB1",
           "EHW_PORT2": "/dev/ttyUSB3 ", "EHW_BAUD": "fast", "EHW_UART_LINE": "bogus",
           "EHW_LINE_FAULTS": "flip=2", "EHW_FPGA_TOOLS": " build"}


def test_every_user_variable_has_a_garbage_case():
    assert set(GARBAGE) == {n for n, v in environ.VARIABLES.items() if not v.internal}


@pytest.mark.parametrize("name", sorted(GARBAGE))
def test_a_bad_environment_variable_is_one_error_line(ehw, tmp_path, monkeypatch, name):
    monkeypatch.setenv(name, GARBAGE[name])
    one_error(*ehw("sim", *TINY, "--out", "run")[::2], name)
    assert not (tmp_path / "run").exists()


def test_the_uart_line_variable_is_no_traceback():
    """`EHW_UART_LINE=bogus ehw sim --backend uart` ended in a ValueError traceback, exit 1."""
    proc = subprocess.run([sys.executable, "-m", "cosim.cli.main", "sim", "--backend", "uart", "--targets", "1"],
                          cwd=REPO_ROOT, capture_output=True, text=True,
                          env={**os.environ, "EHW_UART_LINE": "bogus", "PYTHONPATH": str(REPO_ROOT)})
    one_error(proc.returncode, proc.stderr, "EHW_UART_LINE", "bogus", "hdl, cocotbext")


def test_no_other_module_reads_the_environment():
    """``base.environ`` is the one reader; elsewhere only what a child process inherits is passed
    on (PYTHONPATH, PATH) or a command's settings saved and put back (``hdl_environment``)."""
    import re

    passed_on = {("cosim/cli/options.py", "saved = {k: os.environ.get(k) for k in values}"),
                 ("cosim/boards/cocotb_run.py", 'os.environ.get("PYTHONPATH", "")'),
                 ("cosim/boards/cocotb_run.py", 'os.environ["PATH"] = str(root / "bin") + os.pathsep + os.environ["PATH"]')}
    found = []
    for package in ("base", "ga", "sim_world", "hdl", "peers", "formal", "cosim", "benchmarks"):
        for path in sorted((REPO_ROOT / package).rglob("*.py")):
            rel = path.relative_to(REPO_ROOT).as_posix()
            if rel == "base/environ.py":
                continue
            for line in path.read_text().splitlines():
                reads = re.search(r"os\.environ\.get\(|os\.getenv\(|= .*os\.environ\[", line)
                if reads and not any(rel == f and text in line for f, text in passed_on):
                    found.append(f"{rel}: {line.strip()}")
    assert found == []


def test_a_blinding_past_the_last_target_is_refused(ehw):
    one_error(*ehw("sim", *TINY, "--blind-bit", "3", "--blind-after-target", "100")[::2],
               "--blind-bit 3", "--blind-after-target 100", "1 targets")


def test_a_failed_start_leaves_the_out_folder_as_it_was(ehw, tmp_path):
    (tmp_path / "empty").mkdir()
    one_error(*ehw("sim", "--resume", "--out", "empty", *TINY)[::2], "checkpoint.json")
    assert list((tmp_path / "empty").iterdir()) == []
    # a fresh --out that cannot start (no board on the port): no folder at all
    one_error(*ehw("sim", *TINY, "--backend", "serial", "--port", str(tmp_path / "ttyNONE"), "--out", "new")[::2],
               "ttyNONE")
    assert not (tmp_path / "new").exists()
    # a resumed run whose board is missing: its files as they were, byte for byte
    assert ehw("sim", *TINY, "--out", "run")[0] == 0
    (tmp_path / "run/summary.json").unlink()
    def files():  # the lock file stays, naming its last holder: not a result
        return {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir() if p.name != ".lock"}

    before = files()
    one_error(*ehw("sim", "--resume", "--out", "run", "--backend", "serial", "--port",
                    str(tmp_path / "ttyNONE"), "--quiet")[::2], "ttyNONE")
    assert files() == before and (tmp_path / "run/.lock").exists()


def _as_in_the_foreground():
    """A shell's background job (``make test &``) starts its children with SIGINT ignored, and
    Python then never raises KeyboardInterrupt: the run under test gets the foreground's default."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_sigterm_prints_the_same_line_as_sigint(tmp_path):
    for signum, status in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        proc = subprocess.Popen([sys.executable, "-m", "cosim.cli.main", "sim", "--targets", "64",
                                 "--out", str(tmp_path / signum.name), "--quiet", "--no-plots"],
                                cwd=REPO_ROOT, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
                                preexec_fn=_as_in_the_foreground)
        deadline = time.monotonic() + 120
        while not (tmp_path / signum.name / ".lock").exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == status, err
        assert err.strip().splitlines() == ["error: interrupted"], err
