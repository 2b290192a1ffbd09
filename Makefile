# Shot-build entry points. Each target creates the virtualenv it needs.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint bench examples clean

# The Khronos glTF Validator (npm) that the export tests run; needs node and npm.
VALIDATOR := tools/gltf-validator/node_modules/.installed

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

## demo: install, then build the bundled building shot (voxelize, simulate, export)
demo: $(STAMP)
	$(BIN)/blastvox run examples/building/scene.toml
	$(BIN)/blastvox info out/building/sim.npz

$(VALIDATOR): tools/gltf-validator/package-lock.json
	npm ci --prefix tools/gltf-validator --no-audit --no-fund --loglevel=error
	touch $(VALIDATOR)

## test: install, then lint and run the whole test suite
test: $(STAMP) $(VALIDATOR)
	$(BIN)/ruff check blastvox tests benchmarks
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check blastvox tests benchmarks

## examples: build all bundled example shots (house, building, logo) into out/
examples: $(STAMP)
	for scene in examples/*/scene.toml; do $(BIN)/blastvox run $$scene || exit 1; done

## bench: print the benchmark tables
bench: $(STAMP)
	$(BIN)/python benchmarks/voxelize.py
	$(BIN)/python benchmarks/convergence.py

clean:
	rm -rf out .pytest_cache
