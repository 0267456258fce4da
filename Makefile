# Two commands do all set-up on a fresh machine: `make run` and `make test`.
#   make run    installs kapsel-py with what a run needs (+ matplotlib for the picture),
#               runs the manual's sample in samples/, reports its time, draws the last snapshot
#   make test   installs the test tools too (pytest, hypothesis, vtk, ovito, matplotlib, and
#               mpi4py + mpich for the distributed tests; strace from apt), runs the fast suite
#   make bench  installs the benchmark extra, runs the benchmarks
# pip's own output goes to .venv/pip-<what>.log and is shown only when an install fails.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install run test bench clean

# $(call pip_install,<extra>,<what it installs, one line>)
define pip_install
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@echo "Installing into $(VENV): $(2) (pip log: $(VENV)/pip-$(1).log)"
	@$(BIN)/python -m pip install 'pip>=21.3' > $(VENV)/pip-$(1).log 2>&1 \
	  && $(BIN)/python -m pip install -e '.[$(1)]' >> $(VENV)/pip-$(1).log 2>&1 \
	  || { tail -n 40 $(VENV)/pip-$(1).log; echo "pip install failed; full log: $(VENV)/pip-$(1).log"; exit 1; }
	@touch $@
endef

$(VENV)/.installed-plot: pyproject.toml
	$(call pip_install,plot,kapsel-py and numpy scipy pyfftw h5py lark orjson numba (the run) + matplotlib (the picture))

$(VENV)/.installed-test: pyproject.toml
	$(call pip_install,test,kapsel-py + test tools: pytest hypothesis vtk ovito matplotlib mpi4py mpich)

$(VENV)/.installed-bench: pyproject.toml
	$(call pip_install,bench,kapsel-py + benchmark tools: matplotlib)

# the numba kernels compiled ahead of time for this machine (kapsel/build_kernels.py): runs
# load them without numba; remade when a kernel's source changes.  A failed build leaves the
# JIT (the same numbers), so it does not stop the install.  (Listed after the venv
# install in each target: make builds the prerequisites in order.)
KERNEL_SRC := $(wildcard kapsel/*/*_kernels.py) kapsel/mesh/stencils.py kapsel/build_kernels.py
kapsel/mesh/_aot_kernels.json: $(KERNEL_SRC)
	@echo "Compiling the kernels ahead of time (python -m kapsel.build_kernels)"
	@$(BIN)/python -m kapsel.build_kernels || true

install: $(VENV)/.installed-plot kapsel/mesh/_aot_kernels.json

run: $(VENV)/.installed-plot kapsel/mesh/_aot_kernels.json
	@echo "Running the manual's sample (samples/input.udf: Navier_Stokes_Cahn_Hilliard_FDM, 32^3, 8 particles, 1000 steps)"
	@cd samples && t0=$$(date +%s.%N) \
	  && $(abspath $(BIN))/kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf --overwrite --seed 1 \
	  && t1=$$(date +%s.%N) \
	  && echo "$$t0 $$t1" | awk '{printf "Sample run took %.1f s (wall clock, measured by make run)\n", $$2 - $$1}'
	@echo "Output written to samples/: output.udf, restart.udf, *.h5 and *.xmf (ParaView)"
	@$(BIN)/kapsel-py analyze show samples

# strace (Debian's package) injects kills and ENOSPC at exact system calls
# (tests/integration/test_kill_points.py; skipped where it cannot be installed)
test: $(VENV)/.installed-test kapsel/mesh/_aot_kernels.json
	@command -v strace > /dev/null 2>&1 || { echo "Installing strace (apt-get) for the kill-point tests"; \
	  { apt-get update -qq && apt-get install -y -qq strace; } > $(VENV)/apt-strace.log 2>&1 \
	  || echo "strace could not be installed (log: $(VENV)/apt-strace.log): the kill-point tests are skipped"; }
	$(BIN)/python -m pytest -q -m "not slow" --durations=25

bench: $(VENV)/.installed-bench
	$(BIN)/python bench/bench_udf.py
	$(BIN)/python bench/bench_spectral.py
	$(BIN)/python bench/bench_spm.py
	$(BIN)/python bench/bench_mac.py
	$(BIN)/python bench/bench_fdm.py
	$(BIN)/python bench/bench_cna.py
	$(BIN)/python bench/bench_output.py
	@if [ -n "$$KREF_CPP" ]; then $(BIN)/python bench/bench_vs_original.py && $(BIN)/python bench/parity.py; \
	  else echo "bench_vs_original.py and parity.py skipped: they run the original (set KREF_CPP; see ../shared/kref/README.md)"; fi
	$(BIN)/python bench/work_precision.py
	$(BIN)/python bench/stability_map.py

clean:
	rm -rf $(VENV) build *.egg-info kapsel/mesh/_aot_kernels*
