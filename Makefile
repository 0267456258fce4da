# Two commands do all set-up on a fresh machine: `make run` and `make test`.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install run test bench clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	cd samples && ../$(BIN)/kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf --overwrite --seed 1
	@echo "Output written to samples/: output.udf, restart.udf, *.h5 and *.xmf"

test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

bench: $(STAMP)
	$(BIN)/python bench/bench_udf.py
	$(BIN)/python bench/bench_spectral.py
	$(BIN)/python bench/bench_spm.py
	$(BIN)/python bench/bench_mac.py
	$(BIN)/python bench/bench_fdm.py
	$(BIN)/python bench/bench_cna.py
	$(BIN)/python bench/bench_vs_original.py

clean:
	rm -rf $(VENV) build *.egg-info
