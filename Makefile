# calbench — two commands on a fresh machine: `make run` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: install run test test-fast bench fuzz lint browser clean

install: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# Debian's chromium for the dashboard tests (Playwright drives it through executablePath) and
# poppler-utils (pdftotext, pdftoppm) for the tests that read the certificate PDF page by page.
browser:
	@if [ ! -x /usr/bin/chromium ] || ! command -v pdftoppm >/dev/null; then \
	  if command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium poppler-utils >/dev/null) \
	      || echo "chromium or poppler-utils could not be installed: those tests will be skipped"; \
	  else echo "no root/apt-get: browser and PDF-page tests will be skipped"; fi; \
	fi

run: install
	$(BIN)/calbench serve --sim --host 127.0.0.1 --port 8000

SRC := bench drivers db station api tests benchmarks

# The whole suite after the static checks (what CI runs).
test: install browser lint
	$(BIN)/python -m pytest -n 2 --dist loadgroup --durations=30

# Everything but Monte-Carlo studies, whole simulated runs and the browser: the edit-test loop.
test-fast: install
	$(BIN)/python -m pytest -n 2 --dist loadgroup -q -m "not slow and not browser"

bench: install
	$(BIN)/python -m benchmarks --record

# Long fuzzing: the property-based input tests with 2000 examples each, then the CLI mutation
# fuzzer (800 mutants of a recording through calibrate and diagnose; exit 1 on any bug class).
fuzz: install
	CALBENCH_FUZZ_EXAMPLES=2000 $(BIN)/python -m pytest -q -p no:cacheprovider tests/bench/test_fuzz_inputs.py tests/api/test_fuzz_schemas.py
	$(BIN)/python -m benchmarks.fuzz_cli 800

# ruff (rules and format), mypy (strict flags on every package: pyproject.toml), layer contracts.
lint: install
	$(BIN)/ruff check $(SRC)
	$(BIN)/ruff format --check $(SRC)
	$(BIN)/mypy
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
