# Two commands on a fresh machine: `make demo` (the main job) and `make test`.
# `make test` runs every test, the heavy ones included (installing a wheel, torchrun, a Ray
# head, a browser, killed and resumed runs, simulated data sets): the command CI runs.
# `make test-quick` leaves the heavy ones out: the loop while editing (minutes, not twenty).
VENV := .venv
# the test processes (pytest-xdist); 0: one process, in order
TEST_WORKERS ?= 2
STAMP := $(VENV)/.installed

.PHONY: install demo test test-quick lint format clean

$(STAMP): pyproject.toml scripts/install.sh
	bash scripts/install.sh
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/loosefit demo --out out/demo

test: $(STAMP)
	$(VENV)/bin/ruff check src tests bench
	$(VENV)/bin/ruff format --check src tests bench
	$(VENV)/bin/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal --durations=25

test-quick: $(STAMP)
	$(VENV)/bin/ruff check src tests bench
	$(VENV)/bin/ruff format --check src tests bench
	$(VENV)/bin/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal --durations=10 -m "not slow and not gpu and not heavy"

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests bench

format: $(STAMP)
	$(VENV)/bin/ruff format src tests bench

clean:
	rm -rf $(VENV) out
