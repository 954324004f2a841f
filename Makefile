# Two commands do all set-up: `make demo` (reproduce the paper) and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= results

.PHONY: demo test test-all bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lsindy reproduce --out $(OUT)
	$(VENV)/bin/lsindy swingup --out $(OUT) --json $(OUT)/swingup.json

test: $(STAMP)
	$(PY) -m pytest -q -m "not slow"

test-all: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) benchmarks/bench_search.py
	$(PY) benchmarks/bench_mpc.py
	$(PY) benchmarks/noise_sweep.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
