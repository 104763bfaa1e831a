# Two commands do all set-up: `make demo` (main job, ~3 CPU-minutes) and `make test` (the test suite).
# Both create .venv with Python 3.12 if it is missing and install the package into it.
VENV ?= .venv
PY := $(VENV)/bin/python
# test files run in this many processes (pytest-xdist; a file's tests share one process and its fixtures), handed
# out longest first (tests/durations.json, tests/conftest.py)
TEST_WORKERS ?= 2
PYTHON312 ?= $(shell command -v python3.12 || command -v python3)

.PHONY: install demo test clean

$(VENV)/.installed: pyproject.toml
	@test -x $(PY) || $(PYTHON312) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@touch $@

install: $(VENV)/.installed

demo: install
	$(PY) -m lerobot_unidextok.demo $(ARGS)

test: install
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder $(ARGS)

clean:
	rm -rf $(VENV) outputs .pytest_cache
