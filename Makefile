# uwcosim: `make demo` and `make test` do all set-up on a fresh machine (python3 >= 3.11, gcc).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
UWC    := $(VENV)/bin/uwcosim
STAMP  := $(VENV)/.installed

.PHONY: demo test fmus lint bench baselines clean chromium wheel-test

$(STAMP): pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

fmus: $(STAMP)
	$(UWC) fmu build

demo: fmus
	$(UWC) run scenarios/tan_terrain.toml --out runs/demo --force

# the HTML report tests open the page in a real headless Chromium (Debian's package)
chromium:
	@command -v chromium >/dev/null || command -v chromium-browser >/dev/null || \
	  { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && \
	    { apt-get update -q >/dev/null; apt-get install -y -q chromium >/dev/null; }; } || \
	  echo "chromium not installed: the HTML report browser tests will be skipped"

# the tests in one process per core (pytest-xdist); `pytest -n 0` runs them in one
test: fmus chromium
	$(PY) -m pytest -q -n auto

# the wheel alone (part of `make test` too): built, installed into a fresh venv without
# downloads, run from an empty folder (list/run/campaign/baseline check/demo/docs)
wheel-test: $(STAMP)
	$(PY) -m pytest -q tests/test_cli_everyday.py -k wheel

baselines: fmus
	$(UWC) baseline update

lint: $(STAMP)
	$(VENV)/bin/ruff check uwcosim tests benchmarks

bench: fmus
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) -m pip install --quiet --no-deps particles  # declares numpy<2; runs with numpy 2
	$(PY) benchmarks/bench_master.py
	$(PY) benchmarks/bench_filters.py
	$(PY) benchmarks/bench_projection.py
	$(PY) benchmarks/bench_rbpf.py

clean:
	rm -rf runs fmus/*.fmu fmus/.build build *.egg-info
