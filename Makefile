# Shot-build entry points. Each target creates the virtualenv it needs.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-fast goldens lint bench verify examples previews clean

# The Khronos glTF Validator (npm) that the export tests run; needs node and npm.
VALIDATOR := tools/gltf-validator/node_modules/.installed

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]' -c constraints.txt
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

## test: install, then lint and run the whole test suite (a test file per CPU, up to 4 at once)
PYTEST_PARALLEL := -n auto --maxprocesses 4 --dist loadfile
test: $(STAMP) $(VALIDATOR) $(BLENDER_STAMP)
	$(BIN)/ruff check blastvox tests benchmarks
	$(BIN)/python -m pytest -q $(PYTEST_PARALLEL)

## test-fast: the everyday lane (no subprocess shots, goldens or Blender): a couple of minutes
test-fast: $(STAMP)
	$(BIN)/ruff check blastvox tests benchmarks
	$(BIN)/python -m pytest -q -m "not slow" $(PYTEST_PARALLEL)

## goldens: refresh examples/golden/ from the current code (say why in the commit)
goldens: $(STAMP)
	for s in house building logo; do $(BIN)/blastvox run examples/$$s/scene.toml -B -q || exit 1; \
	  cp out/$$s/sim.npz examples/golden/$$s.sim.npz; done
	cp out/house/shot.glb examples/golden/house.glb

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

## bench: run every benchmark (48 minutes on a 2-core EPYC) and rewrite docs/benchmarks.md
## with their tables (and docs/images/tradeoff.png); progress goes to the terminal
BENCH_DOC := docs/benchmarks.md
bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]' -c constraints.txt
	@set -e; out=$(BENCH_DOC).partial; trap 'rm -f "$$out" "$$out.perf"' EXIT; \
	section() { printf '\n## %s\n\n`python benchmarks/%s`\n\n' "$$1" "$$2"; }; \
	{ \
	  echo '# Benchmarks'; echo; \
	  echo "<!-- Written by \`make bench\` at git $$(git describe --always --dirty 2>/dev/null \
	    || echo unknown) on $$(date -u +%F). Do not edit by hand: the next \`make bench\` rewrites it. -->"; echo; \
	  echo 'The speed and accuracy of blastvox, measured by the scripts in `benchmarks/`.'; \
	  echo 'Each section is the output of one script: its machine line (platform, CPU,'; \
	  echo 'CPU count, load average, versions), then its tables. What each column means,'; \
	  echo 'the cases and the targets: [`benchmarks/README.md`](../benchmarks/README.md).'; \
	  echo 'How to read the speed/accuracy trade for a shot:'; \
	  echo '[user guide](user-guide.md#choosing-voxel-size-and-time-step).'; \
	  echo 'Targets are reported, not gated.'; \
	  section Voxelize voxelize.py; $(BIN)/python benchmarks/voxelize.py; \
	  section 'Time-step convergence' convergence.py; $(BIN)/python benchmarks/convergence.py; \
	  section Simulate simulate.py; $(BIN)/python benchmarks/simulate.py; \
	  section Performance performance.py; \
	  $(BIN)/python benchmarks/performance.py > "$$out.perf"; sed 's/^## /### /' "$$out.perf"; \
	  section Export export.py; $(BIN)/python benchmarks/export.py; \
	  section 'Rubble faces' rubble.py; $(BIN)/python benchmarks/rubble.py; \
	  section 'USD against glTF at 20,000 pieces' export_usd.py; \
	  $(BIN)/python benchmarks/export_usd.py; \
	  section 'Particle volumes' 'volumes.py --voxel 0.1 0.2'; $(BIN)/python benchmarks/volumes.py --voxel 0.1 0.2; \
	  section Preview preview.py; $(BIN)/python benchmarks/preview.py; \
	  section 'Wedges on Dask' wedge.py; $(BIN)/python benchmarks/wedge.py; \
	  section 'Contact cost' contacts.py; $(BIN)/python benchmarks/contacts.py; \
	  section 'Stacking against PyBullet' stacking.py; $(BIN)/python benchmarks/stacking.py; \
	  section "The building's rubble pile against PyBullet" pile.py; \
	  $(BIN)/python benchmarks/pile.py; \
	  section 'Threads under load' threads.py; $(BIN)/python benchmarks/threads.py; \
	  section 'Stress solver' stress.py; $(BIN)/python benchmarks/stress.py; \
	  section 'Export at scale' 'export_scale.py --quick'; \
	  $(BIN)/python benchmarks/export_scale.py --quick; \
	  section 'Speed/accuracy trade' 'tradeoff.py --plot docs/images/tradeoff.png'; \
	  $(BIN)/python benchmarks/tradeoff.py --plot docs/images/tradeoff.png; \
	  printf '\n![Wall time against error: combined (Pareto fronts drawn) and per metric]'; \
	  printf '(images/tradeoff.png)\n'; \
	} > "$$out"; \
	mv "$$out" $(BENCH_DOC); echo "wrote $(BENCH_DOC)"

## verify: the verification suite (issue 34): canonical scenes against their published
## references over voxel size x dt (about 15 minutes on 2 cores, 2026-11-30); rewrites its tables in
## docs/physics.md ("Verification"). `python benchmarks/verification.py --quick`: ~1 minute
verify: $(STAMP)
	$(BIN)/python benchmarks/verification.py --docs
	$(BIN)/python benchmarks/verification_support.py --docs

## clean: outputs, and numba's compiled kernels of this source tree (never needed after
## an edit: the cache is keyed on the source, see blastvox/_kernel_cache.py)
clean:
	rm -rf out .pytest_cache
	find blastvox -name '*.nbi' -delete -o -name '*.nbc' -delete
	[ ! -x $(BIN)/python ] || rm -rf "$$($(BIN)/python -c 'import blastvox.jit; print(blastvox.jit.KERNEL_CACHE)')"
