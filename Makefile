# contactvisco: `make demo` and `make test` install what they need first (Debian 12, as root
# or with sudo). Two routes to FEniCSx:
#   STACK=debian (default): Debian's DOLFINx 0.5 with hypre and Open MPI, in .venv
#   STACK=pip:              PyPI's DOLFINx 0.11 wheel (dolfinx-solver-real) with its own MPICH,
#                           on Python >= 3.12, in .venv-pip
SHELL := /bin/bash
STACK ?= debian
NP ?= 2

ifeq ($(STACK),pip)
VENV := .venv-pip
# What pip's gmsh and VTK load from the system, and a C compiler for the form JIT.
APT_PACKAGES := gcc libglu1-mesa libxcursor1 libxft2 libxinerama1 libgl1 libxrender1
MPIRUN := $(CURDIR)/$(VENV)/bin/mpiexec -n $(NP)
else ifeq ($(STACK),debian)
VENV := .venv
# GetFEM's Python interface runs the independent solvers that tests/integration/test_peer.py
# and test_two_body_peer.py compare with (they are skipped where it is missing).
APT_PACKAGES := python3-dolfinx-real python3-gmsh python3-venv python3-pytest \
                python3-matplotlib python3-scipy openmpi-bin python3-getfem
MPIRUN := mpirun -n $(NP)
else
$(error STACK must be debian or pip, not '$(STACK)')
endif
PY := $(VENV)/bin/python

# Open MPI refuses root unless told; harmless otherwise (and ignored by MPICH).
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1

.PHONY: install demo test test-serial test-parallel test-slow test-all benchmark benchmark-newton benchmark-peer \
        benchmark-scaling benchmark-startup \
        benchmark-reliability benchmark-linear clean apt-packages compare-stacks figures notebook docs

install: $(VENV)/.installed

apt-packages:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages: $$missing"; \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$SUDO apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

ifeq ($(STACK),pip)
# A Python >= 3.12 that runs: python3.13 or python3.12 on PATH, else pyenv's newest.
FIND_PYTHON := for p in python3.13 python3.12 \
	  $$(ls -d $$(pyenv root 2>/dev/null)/versions/3.1[2-9]*/bin/python3 2>/dev/null | sort -rV); do \
	  $$p -c 'import sys; assert sys.version_info >= (3, 12)' 2>/dev/null && { command -v $$p; exit 0; }; \
	done; exit 1

$(VENV)/.installed: pyproject.toml | apt-packages
	@if [ ! -x $(PY) ]; then \
	  python=$$($(FIND_PYTHON)) || { echo "The PyPI route needs Python >= 3.12 (DOLFINx 0.11 wheels): install python3.12 or python3.13 (e.g. with pyenv) and run again." >&2; exit 1; }; \
	  echo "PyPI route: $$python"; $$python -m venv $(VENV); \
	fi
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q dolfinx-solver-real gmsh -e '.[viz,dev]'
	$(PY) -m contactvisco --version
	touch $@
else
# The constraints keep Debian's numpy: pip's numpy 2 breaks Debian's petsc4py.
$(VENV)/.installed: pyproject.toml constraints.txt | apt-packages
	[ -x $(PY) ] || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -c constraints.txt --no-build-isolation -e '.[viz,dev]'
	$(PY) -m contactvisco --version
	touch $@
endif

demo: install
	$(VENV)/bin/contactvisco run paper --out results/paper$(if $(filter pip,$(STACK)),-pip)

# The tests in tiers (markers in pyproject.toml; docs/testing.md):
#   make test       every test not marked slow on 1 rank (PYTEST_WORKERS pytest workers), then
#                   the tests marked mpi on $(NP) ranks: the README's test command, and CI's;
#   make test-slow  the tests marked slow, on 1 rank; CI runs them once, on the Debian route;
#   make test-all   every test on 1 rank and on $(NP) ranks.
test: test-serial test-parallel

# A deadlock between ranks must fail the run, not hang it.
TEST_TIMEOUT ?= 1800
# Two workers use both cores of a 2-core machine (pytest-xdist); 1 runs the tests in one process.
PYTEST_WORKERS ?= 2
XDIST := $(if $(filter-out 0 1,$(PYTEST_WORKERS)),-n $(PYTEST_WORKERS) --dist loadgroup)
# Extra pytest arguments for every tier, e.g. PYTEST_ARGS="--durations=30".
PYTEST_ARGS ?=
# JUNIT=DIR: each pass also writes a JUnit report DIR/<stack>-<pass>.xml (.ci/tally.py reads them).
JUNIT ?=
junit = $(if $(JUNIT),--junitxml=$(JUNIT)/$(STACK)-$(1).xml)

test-serial: install
	timeout $(TEST_TIMEOUT) $(PY) -m pytest -q $(XDIST) -m "not slow" $(PYTEST_ARGS) \
	  $(call junit,1rank) tests

# The tests marked processes start their own 2-rank jobs from the 1-rank pass.
test-parallel: install
	timeout $(TEST_TIMEOUT) $(MPIRUN) $(PY) -m pytest -q --color=no -m "mpi and not processes" \
	  $(PYTEST_ARGS) $(call junit,2ranks) tests

test-slow: install
	timeout $(TEST_TIMEOUT) $(PY) -m pytest -q $(XDIST) -m slow $(PYTEST_ARGS) $(call junit,slow) tests

test-all: install
	timeout $(TEST_TIMEOUT) $(PY) -m pytest -q $(XDIST) $(PYTEST_ARGS) $(call junit,all-1rank) tests
	timeout $(TEST_TIMEOUT) $(MPIRUN) $(PY) -m pytest -q --color=no $(PYTEST_ARGS) \
	  $(call junit,all-2ranks) tests

# Benchmarks write their tables to benchmarks/results/ (run by hand; not part of the tests;
# benchmarks/README.md).
BENCH := benchmarks
benchmark: install
	$(PY) $(BENCH)/performance/paper_scaling.py && $(PY) $(BENCH)/performance/reductions.py && \
	  $(PY) $(BENCH)/performance/scenes.py && $(MPIRUN) $(PY) $(BENCH)/performance/scenes.py && \
	  $(PY) $(BENCH)/accuracy/verification.py && $(PY) $(BENCH)/accuracy/tradeoff.py && \
	  $(PY) $(BENCH)/robustness/extremes.py && $(PY) $(BENCH)/performance/time_linearity.py

# Newton iterations and factorizations of the paper scene per size, with and without the
# predicted first iterate (about 2 minutes): docs/scaling.md.
benchmark-newton: install
	$(PY) $(BENCH)/performance/newton_work.py

# The paper scene's Newton time against a semismooth Newton solver written in GetFEM on the same
# discrete problem, contact values compared first (about 3 minutes, 1 rank, Debian route:
# GetFEM's Python interface is the Debian package python3-getfem): docs/scaling.md.
benchmark-peer: install
	@$(PY) -c 'import getfem' 2>/dev/null || { echo "benchmark-peer needs GetFEM's Python interface: apt-get install -y python3-getfem (as root; the Debian route's $(VENV) sees it through its system site packages)" >&2; exit 1; }
	$(PY) $(BENCH)/performance/peer.py

# The paper scene's linear solves: time per analysis, factorization and solve of each direct
# solver and ordering PETSc has (32^2 to 128^2, 1 rank), Krylov iterations and Newton time of
# BoomerAMG variants (or GAMG's) at 128^2 on 1 and 2 ranks (about 15 minutes): docs/scaling.md.
benchmark-linear: install
	$(PY) $(BENCH)/performance/linear_solvers.py --sizes 32 64 && \
	  $(PY) $(BENCH)/performance/linear_solvers.py --sizes 128 --tag 128 \
	    --only "MUMPS (default)" METIS AMD nd UMFPACK && \
	  $(PY) $(BENCH)/performance/linear_solvers.py --part iterative --sizes 128 --rounds 1 && \
	  $(MPIRUN) $(PY) $(BENCH)/performance/linear_solvers.py --part iterative --sizes 128 --rounds 1

# Where the wall time of `contactvisco run paper` goes, the whole process (interpreter start,
# imports, set-up, steps, per-step output, figures, exit): median of 3 runs after a warm-up,
# with and without figures, the load recorded (about a minute): docs/scaling.md.
benchmark-startup: install
	$(PY) $(BENCH)/performance/startup.py

# Size, solver and rank scaling (about an hour on 2 cores; each configuration its own mpirun).
benchmark-scaling: install
	$(PY) $(BENCH)/performance/scaling.py

# Faults (kill -9 campaigns on 1 and 2 ranks, signals, full disk, damaged checkpoints; about
# 10 minutes) and the cost of the per-step output: docs/reliability.md.
benchmark-reliability: install
	$(PY) $(BENCH)/performance/output_cost.py && \
	  $(MPIRUN) $(PY) $(BENCH)/performance/output_cost.py --skip-runs && \
	  $(PY) $(BENCH)/robustness/reliability.py --part kill1 && \
	  $(PY) $(BENCH)/robustness/reliability.py --part kill2 && \
	  $(PY) $(BENCH)/robustness/reliability.py --part other && \
	  $(PY) $(BENCH)/robustness/reliability.py --part paths

# Both routes give the paper scene's answer to 1e-10 on 1 and 2 ranks
# (benchmarks/accuracy/stacks.py).
compare-stacks:
	$(MAKE) STACK=debian install
	$(MAKE) STACK=pip install
	python3 $(BENCH)/accuracy/stacks.py

# The figures of README.md and docs/ with their signatures (tests/integration/test_figures.py
# checks them), and the picture of docs/paraview.md (a run read back as ParaView reads it).
figures: install
	$(PY) docs/make_figures.py
	$(PY) docs/paraview_view.py

# The demos as notebooks in JupyterLab, on a kernel of this environment (the demos declare
# none: they open on contactvisco-$(STACK)); root needs --allow-root. What the demos write
# goes to demos/results/, which git ignores.
# On the Debian route markdown-it-py and mdit-py-plugins stay at the versions Debian's
# myst-parser (the documentation's) requires. jupytext-config makes a double click open a
# demo's .py file as a notebook (the user's JupyterLab settings).
NOTEBOOK_PINS := $(if $(filter debian,$(STACK)),-c constraints.txt 'markdown-it-py<3' 'mdit-py-plugins<0.4')
notebook: install
	$(PY) -m pip install -q $(NOTEBOOK_PINS) jupyterlab jupytext
	$(PY) -m ipykernel install --user --name contactvisco-$(STACK) \
	  --display-name "contactvisco ($(STACK))"
	$(VENV)/bin/jupytext-config set-default-viewer python
	$(VENV)/bin/jupyter lab demos/ \
	  --MappingKernelManager.default_kernel_name=contactvisco-$(STACK) \
	  $$([ "$$(id -u)" = 0 ] && echo --allow-root)

# The documentation (docs/, Sphinx + MyST + numpydoc from Debian's packages), built offline
# into build/docs with the Debian route's Python, so that autodoc imports the package; every
# warning (a broken internal link or anchor included) fails it. The demos are executed as
# notebooks first, two at a time (docs/demo_pages.py; cached in build/docs-demos/): budget
# 3 minutes from an empty build/ on an idle 2-core machine, 20 s with the cache
# (docs/installation.md has the measurements). Then the relative file links
# of README.md and docs/*.md (tests/unit/test_docs_links.py) and the built pages: no network,
# MathJax from the build (Debian's libjs-mathjax), no raw math or table (test_docs_built.py).
DOCS_APT_PACKAGES := python3-sphinx python3-myst-parser python3-numpydoc python3-sphinx-rtd-theme \
                     libjs-mathjax

docs:
	$(MAKE) STACK=debian install
	$(MAKE) apt-packages APT_PACKAGES="$(DOCS_APT_PACKAGES)"
	.venv/bin/python -m sphinx -W --keep-going -n -b html docs build/docs
	.venv/bin/python -m pytest -q tests/unit/test_docs_links.py tests/unit/test_docs_built.py
	@echo "documentation: build/docs/index.html"

clean:
	rm -rf results build *.egg-info
