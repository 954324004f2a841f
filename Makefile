# Two commands do all set-up: `make demo` (reproduce the paper) and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= results
BENCH  ?= bench-results

.PHONY: demo test test-slow test-all bench bench-sweep clean

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt -e '.[test,bench,mujoco,gym,dask]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lsindy reproduce --out $(OUT)
	$(VENV)/bin/lsindy swingup --out $(OUT) --json $(OUT)/swingup.json

test: $(STAMP)
	$(PY) -m pytest -q -n auto -m "not slow"

test-slow: $(STAMP)     # only the cases marked slow (CI runs them after make test)
	$(PY) -m pytest -q -n auto -m slow

test-all: $(STAMP)
	$(PY) -m pytest -q -n auto

# Benchmarks write into $(BENCH)/ (untracked); the tracked benchmarks/results/ are regenerated on
# purpose, by running a script without its output option.
bench: $(STAMP)          # quick speed benchmarks: search (~1.5 min) and MPC (~7 min)
	mkdir -p $(BENCH)
	$(PY) benchmarks/bench_search.py --out $(BENCH)/search.json
	$(PY) benchmarks/bench_mpc.py --json $(BENCH)/mpc.json

bench-sweep: $(STAMP)    # the noise sweep, ~1 h on 2 cores
	mkdir -p $(BENCH)
	$(PY) benchmarks/noise_sweep.py --out $(BENCH) --figures $(BENCH)

clean:
	rm -rf $(VENV) $(OUT) $(BENCH) .pytest_cache
