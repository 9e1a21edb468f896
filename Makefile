# uwcosim: `make demo` and `make test` do all set-up on a fresh machine (python3 >= 3.11, gcc).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
UWC    := $(VENV)/bin/uwcosim
STAMP  := $(VENV)/.installed

.PHONY: demo test fmus lint bench baselines clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

fmus: $(STAMP)
	$(UWC) fmu build

demo: fmus
	$(UWC) run scenarios/tan_terrain.toml --out runs/demo

test: fmus
	$(PY) -m pytest -q

baselines: fmus
	$(UWC) baseline update

lint: $(STAMP)
	$(VENV)/bin/ruff check uwcosim tests benchmarks

bench: fmus
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) benchmarks/bench_master.py
	$(PY) benchmarks/bench_filters.py
	$(PY) benchmarks/bench_projection.py
	$(PY) benchmarks/bench_rbpf.py

clean:
	rm -rf runs fmus/*.fmu fmus/.build build *.egg-info
