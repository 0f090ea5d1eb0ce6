# Two commands are the contract: `make sim` (the main job) and `make test`.
# Everything else is set up on demand: the virtual environment, the Python dependencies pinned in
# pyproject.toml, and Debian's iverilog (Icarus Verilog, needed by cocotb).

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
BACKEND ?= reference
# HDL backends: controllers per population the HDL evaluator evaluates (each checked against the
# reference; the rest come from the reference). 0 = all of them: exact, but about 9 hours in Icarus.
HDL_SAMPLE ?= 1
SEED   ?= 1
SEEDS  ?= 5
JOBS   ?= 2
ARGS   ?=

.PHONY: all test sim offline compare verilog bench arena baseline iverilog venv clean distclean help

all: test

help:
	@echo "make sim       on-line model-based experiment (BACKEND=reference|amaranth|cocotb, SEED=1, HDL_SAMPLE=1)"
	@echo "make test      the whole test suite (creates .venv, installs iverilog if missing)"
	@echo "make offline   off-line model-free experiment"
	@echo "make compare   both methods over SEEDS seeds -> results/compare.md"
	@echo "make verilog   build/verilog/*.v"
	@echo "make bench     speed figures -> results/bench.json"
	@echo "make arena     render the default arena -> results/arena.png"
	@echo "make baseline  run the reactive baseline through the 64 legs"

# The stamp is rebuilt only when pyproject.toml changes, so a second `make test` starts in seconds.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

venv: $(STAMP)

iverilog:
	@if ! command -v iverilog >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "iverilog not found: installing Debian's iverilog"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iverilog) \
	      || { echo "error: apt-get could not install iverilog" >&2; exit 1; }; \
	  else \
	    echo "error: Icarus Verilog (iverilog) is needed by the cocotb tests and is not on PATH." >&2; \
	    echo "       Install it as root: apt-get install iverilog  (or: sudo make iverilog)" >&2; \
	    exit 1; \
	  fi; \
	fi

test: $(STAMP) iverilog
	$(PY) -m pytest -n $(JOBS) $(ARGS)

sim: $(STAMP) iverilog
	EHW_HDL_SAMPLE=$(HDL_SAMPLE) $(PY) -m cosim.online --backend $(BACKEND) --seed $(SEED) $(ARGS)

offline: $(STAMP)
	$(PY) -m cosim.offline --seed $(SEED) $(ARGS)

compare: $(STAMP)
	$(PY) -m cosim.compare --seeds $(SEEDS) $(ARGS)

verilog: $(STAMP)
	$(PY) -m hdl.generate --out build/verilog

bench: $(STAMP) iverilog
	$(PY) -m benchmarks $(ARGS)

arena: $(STAMP)
	$(PY) -m sim_world.render --out results $(ARGS)

baseline: $(STAMP)
	$(PY) -m sim_world.baseline $(ARGS)

clean:
	rm -rf build results sim_build .pytest_cache .hypothesis

distclean: clean
	rm -rf $(VENV) *.egg-info
