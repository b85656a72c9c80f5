# contactvisco: `make demo` and `make test` install what they need first (Debian 12, as root
# or with sudo). Everything else lives in the virtual environment .venv.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
NP ?= 2
APT_PACKAGES := python3-dolfinx-real python3-gmsh python3-venv python3-pytest \
                python3-matplotlib openmpi-bin
# Open MPI refuses root unless told; harmless otherwise.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
MPIRUN := mpirun -n $(NP)

.PHONY: install demo test test-serial test-parallel benchmark benchmark-scaling \
        benchmark-reliability clean

install: $(VENV)/.installed

# The constraints keep Debian's numpy: pip's numpy 2 breaks Debian's petsc4py.
$(VENV)/.installed: pyproject.toml constraints.txt
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages: $$missing"; \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$SUDO apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi
	[ -x $(PY) ] || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -c constraints.txt --no-build-isolation -e '.[viz,dev]'
	$(PY) -c "import dolfinx, contactvisco; print('dolfinx', dolfinx.__version__, 'ok')"
	touch $@

demo: install
	$(VENV)/bin/contactvisco run paper --out results/paper

test: test-serial test-parallel

# A deadlock between ranks must fail the run, not hang it.
TEST_TIMEOUT ?= 1800

test-serial: install
	timeout $(TEST_TIMEOUT) $(PY) -m pytest -q tests

test-parallel: install
	timeout $(TEST_TIMEOUT) $(MPIRUN) $(PY) -m pytest -q --color=no tests

# Benchmarks write their tables to benchmarks/results/ (run by hand; not part of the tests).
benchmark: install
	cd benchmarks && ../$(PY) paper_scaling.py && ../$(PY) reductions.py && \
	  ../$(PY) scenes.py && $(MPIRUN) ../$(PY) scenes.py && ../$(PY) verification.py && \
	  ../$(PY) tradeoff.py && ../$(PY) extremes.py && ../$(PY) time_linearity.py

# Size, solver and rank scaling (about an hour on 2 cores; each configuration its own mpirun).
benchmark-scaling: install
	cd benchmarks && ../$(PY) scaling.py

# Faults (kill -9 campaigns on 1 and 2 ranks, signals, full disk, damaged checkpoints; about
# 10 minutes) and the cost of the per-step output: docs/reliability.md.
benchmark-reliability: install
	cd benchmarks && ../$(PY) output_cost.py && $(MPIRUN) ../$(PY) output_cost.py --skip-runs && \
	  ../$(PY) reliability.py --part kill1 && ../$(PY) reliability.py --part kill2 && \
	  ../$(PY) reliability.py --part other

clean:
	rm -rf results build *.egg-info
