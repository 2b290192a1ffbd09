# Shot-build entry points. Each target creates the virtualenv it needs.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint bench examples previews clean

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

# Blender as a Python module (bpy, tools/blender/requirements.txt) in its own venv: it
# pins its own numpy, and its wheel is for CPython 3.11 only. tests/test_blender_import.py
# imports the USD and glTF exports with it (and skips without it).
BLENDER_PYTHON ?= python3.11
BLENDER_VENV   := .venv-blender
BLENDER_STAMP  := $(BLENDER_VENV)/.installed

.PHONY: blender-venv
## blender-venv: create .venv-blender with bpy, for the Blender import test
blender-venv: $(BLENDER_STAMP)

$(BLENDER_STAMP): tools/blender/requirements.txt
	$(BLENDER_PYTHON) -m venv $(BLENDER_VENV)
	$(BLENDER_VENV)/bin/python -m pip install --quiet -r tools/blender/requirements.txt
	touch $(BLENDER_STAMP)

## test: install, then lint and run the whole test suite
test: $(STAMP) $(VALIDATOR) $(BLENDER_STAMP)
	$(BIN)/ruff check blastvox tests benchmarks
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check blastvox tests benchmarks

## examples: build all bundled example shots (house, building, logo) into out/
examples: $(STAMP)
	for scene in examples/*/scene.toml; do $(BIN)/blastvox run $$scene || exit 1; done

## previews: build the example shots, then render the README's images into docs/images/
PREVIEW_SIZE ?= 480x270
previews: $(STAMP)
	mkdir -p docs/images
	for s in house building logo; do \
	  $(BIN)/blastvox run examples/$$s/scene.toml -q || exit 1; \
	  $(BIN)/blastvox preview out/$$s/sim.npz -o docs/images/$$s.png --size $(PREVIEW_SIZE) -q \
	    || exit 1; \
	done
	$(BIN)/blastvox blast --charge 10 --distance 1,5,20 --plot docs/images/blast.png > /dev/null

## bench: print the benchmark tables
bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	$(BIN)/python benchmarks/voxelize.py
	$(BIN)/python benchmarks/convergence.py
	$(BIN)/python benchmarks/simulate.py
	$(BIN)/python benchmarks/performance.py

## clean: outputs, and numba's compiled-kernel cache (it only watches each kernel's
## own source file: after editing a helper another module inlines, clean)
clean:
	rm -rf out .pytest_cache
	find blastvox -name '*.nbi' -delete -o -name '*.nbc' -delete
