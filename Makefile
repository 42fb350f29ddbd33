# Entry points for a fresh machine:  make run  (the paper's study)  and  make test.
# Each target creates the virtual environment .venv from pyproject.toml first
# (again only when pyproject.toml changed).

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
SNAKEMAKE := $(VENV)/bin/snakemake
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
# The versions of every package the committed results were made with (pip
# constraints: they pin what is installed, they install nothing themselves).
CONSTRAINTS := workflow/envs/constraints.txt
PROFILE := workflow/profiles/default
# Each configuration writes its own results folder (config `results`), its
# report there too: the study results/study, the smoke run results/smoke,
# make reproduction results/reproduction.
SMOKE := --configfile config/smoke.yaml --replace-workflow-config
REPRODUCTION := --configfile config/config.yaml config/scenes/elastic_probes.yaml config/reproduction.yaml

# One Numba cache for every process started from here (the workflow's rules set
# the same directory themselves).
export NUMBA_CACHE_DIR := $(CURDIR)/.numba_cache

.PHONY: venv venv-test run reproduction report smoke test browser bench bench-peers lint clean distclean

venv: $(STAMP)

# The study's packages only (make run, smoke, reproduction, report, bench).
$(STAMP): pyproject.toml $(CONSTRAINTS)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e .
	touch $@

# And the test extras (pytest, shapely, hypothesis, vtk, selenium, the SLURM plugin).
venv-test: $(TEST_STAMP)

$(TEST_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e '.[test]'
	touch $@

# The paper's study (config/config.yaml): all piles, pictures and the analysis,
# in results/study/. While Snakemake runs, a line on the piles done, running and left and the time
# left (python -m workflow.tools study_progress) comes a minute after the start
# (its FIRST_LINE_S), then every PROGRESS_EVERY seconds, and once at the end, into the terminal and logs/make-run.log (through the
# same tee: a second writer appending to the file would be overwritten by
# tee). The trap stops that loop whenever the group ends; the group, and so
# `make run`, exits with Snakemake's status.
PROGRESS := $(PY) -m workflow.tools study_progress
PROGRESS_EVERY := 300

run: venv
	mkdir -p logs
	{ $(PROGRESS) --every $(PROGRESS_EVERY) 2>&1 & progress=$$!; \
	  trap 'kill $$progress 2>/dev/null || true' EXIT; \
	  status=0; $(SNAKEMAKE) --cores all --profile $(PROFILE) 2>&1 || status=$$?; \
	  kill $$progress 2>/dev/null || true; $(PROGRESS) 2>&1 || true; \
	  exit $$status; } | tee logs/make-run.log

# The progress line of the study, once (e.g. from another terminal during
# `make run`); it names the configuration and counts the piles of its results
# folder only (another: python -m workflow.tools study_progress --configfile FILE).
.PHONY: progress
progress: venv
	@$(PROGRESS)

# The study's ensembles, fits and figures, and the table of finished piles,
# rebuilt from the per-pile results committed under docs/reproduction/ alone
# (no state file, no simulation; config/reproduction.yaml): results/reproduction/,
# docs/reproduction/figures/, piles.md; with the extra probes' scene, the
# general fit of the piles whose probes are there. Then its report,
# results/reproduction/report.html.
reproduction: venv
	mkdir -p logs
	$(SNAKEMAKE) reproduction --cores all --profile $(PROFILE) $(REPRODUCTION) 2>&1 | tee logs/make-reproduction.log
	$(SNAKEMAKE) --profile $(PROFILE) $(REPRODUCTION) --report results/reproduction/report.html

# The study's HTML report (snakemake --report, one self-contained page): every
# figure, the pictures and films of the piles, the run-time table, each with
# its caption (workflow/report/), of what the study has made so far (target
# `made`); its first lines name the configuration, the folder and the piles
# there. Open results/study/report.html in a browser.
report: venv
	mkdir -p results/study
	$(SNAKEMAKE) made --profile $(PROFILE) --report results/study/report.html

# Tiny piles (config/smoke.yaml), end to end in minutes, in results/smoke/, and
# their report results/smoke/report.html.
smoke: venv
	mkdir -p logs
	$(SNAKEMAKE) --cores all --profile $(PROFILE) $(SMOKE) 2>&1 | tee logs/make-smoke.log
	$(SNAKEMAKE) --profile $(PROFILE) $(SMOKE) --report results/smoke/report.html

# The test of the report opens it in headless Chromium (tests/test_workflow.py):
# Debian's chromium and chromium-driver, installed here when missing (as root
# with apt-get; otherwise install them and rerun).
browser:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then :; \
	elif command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	  echo "installing chromium and chromium-driver (for the report test)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; \
	else echo "make test needs Chromium and ChromeDriver for the report test: install the" \
	  "Debian packages chromium and chromium-driver (or put chromium and chromedriver on PATH)" >&2; exit 1; fi

# make test changes the machine when run as root: besides Chromium (above),
# tests/test_slurm.py installs Debian's slurmctld, slurmd, slurm-client and
# munge (tests/slurm/cluster.sh) and starts a one-node SLURM cluster (munged,
# slurmctld, slurmd) on this machine; it stops those daemons at its end, the
# packages stay installed. `make test CLUSTER=no` runs the suite without that
# test: nothing of SLURM is installed or started.
CLUSTER ?= yes
ifeq ($(CLUSTER),no)
PYTEST_CLUSTER := -m "not slurm"
endif

test: venv-test browser
	@if [ "$(CLUSTER)" != no ] && [ "$$(id -u)" = 0 ]; then \
	  echo "make test: the SLURM test installs slurmctld, slurmd, slurm-client and munge when" \
	    "missing and starts a one-node cluster, stopped at its end (make test CLUSTER=no leaves it out)"; fi
	$(PY) -m pytest $(PYTEST_CLUSTER)

# The simulator's timings; with LAMMPS installed (make bench-peers) also a
# LAMMPS disk pile of each size and LAMMPS's rounded polygons of each pile,
# timed in the same run, and the ratios to them.
bench: venv
	mkdir -p logs
	$(PY) -m sim bench --sizes 3000,10000,30000 \
	  $$(command -v lmp >/dev/null && echo --peer lammps --peer lammps-polygons) \
	  2>&1 | tee logs/bench.log

# The bench's peers: Debian's lammps package (lmp, with mpirun), its GRANULAR
# package for the disks and its BODY package for the polygons.
bench-peers:
	@if command -v lmp >/dev/null && command -v mpirun >/dev/null; then :; \
	elif command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	  echo "installing Debian's lammps (the bench's reference peer)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq lammps >/dev/null; \
	else echo "make bench-peers needs Debian's lammps package (lmp and mpirun): install it" \
	  "and rerun" >&2; exit 1; fi

lint: venv
	$(SNAKEMAKE) --lint
	$(SNAKEMAKE) --lint $(SMOKE)

# Removes everything the workflow made (results/ except its README: every
# configuration's folder; logs/ of make; logs/ and benchmarks/ of a tree made
# before the results folders; Snakemake's metadata) and the caches; keeps .venv.
clean:
	find results -mindepth 1 -maxdepth 1 ! -name README.md -exec rm -rf {} +
	rm -rf logs benchmarks .bench .snakemake .numba_cache .pytest_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
