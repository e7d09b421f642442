# Two entry points for a new user: `make demo` and `make test`; `make docs` builds the
# documentation site (docs/, mkdocs.yml) into site/.
# Both create .venv on first use; re-running is fast because the install step
# is redone only when pyproject.toml or this Makefile changes. The test install takes
# the optional extras too (Dask distributed, laspy, rasterio for GeoTIFF elevation models)
# so their code paths are tested.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

# Material for MkDocs prints a banner about its successor on every build otherwise.
export NO_MKDOCS_2_WARNING := 1

.PHONY: demo test lint docs bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# The dependencies are byte-compiled at install (pip's default): where PYTHONDONTWRITEBYTECODE
# is set, nothing is compiled later, and every process would compile each module it imports.
$(STAMP): pyproject.toml Makefile | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,cluster,las,geotiff]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/lander demo

# The site is checked after the tests, so that a broken link never hides a test result.
# The tests run on TEST_WORKERS processes (pytest-xdist); `make test TEST_WORKERS=0` runs
# them in this one.
TEST_WORKERS ?= 2
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS)
	$(BIN)/mkdocs build --strict --quiet

lint: $(STAMP)
	$(BIN)/ruff check .

docs: $(STAMP)
	$(BIN)/mkdocs build --strict
	@echo "open site/index.html, or serve it with: $(BIN)/mkdocs serve"

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) build site *.egg-info .pytest_cache .ruff_cache
