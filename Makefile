# Guaranteed state estimator benchmark harness.  `make help` lists the targets.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CONFIGS_ALL   := $(wildcard benchmarks/configs/*.yaml)
CONFIGS_QUICK := benchmarks/configs/quick.yaml
RESULTS ?= results
# worker processes of `make bench` (designs and runs); JOBS=1 runs serially, the only mode whose
# per-step times are undisturbed (parallel ones are marked "(parallel)" in the reports;
# reports/speed.md is always timed serially)
JOBS ?= $(shell getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
# single-threaded BLAS: faster and far less noisy on the small matrices of the observers
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.DEFAULT_GOAL := help
.PHONY: help install test lint docs bench bench-quick report reports check baseline history audit audit-short speed scaling frontier clean

help:  ## list the targets
	@echo "setobs-bench: guaranteed state estimator benchmark harness"
	@echo
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | sed 's/:.*## /\t/' | awk -F'\t' '{printf "  make %-12s %s\n", $$1, $$2}'
	@echo
	@echo "code: observers/ (sets, family loops, plugins builtin/X.py + numerics/X.py), systems/ (models,"
	@echo "scenarios, data), benchmarks/ in wings: run/ (config -> specs -> runner -> executors),"
	@echo "report/ (tables, markdown, html, figures, numbers), gate/ (regression, kernels, policy, audit,"
	@echo "history), timing/ (steps, speed), studies/ (scaling, frontier, alanwar2022); cli.py parses and prints"

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "Python >= 3.10 is required, found " + sys.version.split()[0]'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,dask,docs]'
	@touch $(STAMP)

install: $(STAMP)  ## create .venv and install the project with its test, dask and docs extras

test: $(STAMP)  ## run ruff and the test suite, which builds the docs with -W and runs their examples (CI runs this, then make check)
	$(VENV)/bin/ruff check observers systems benchmarks tests
	$(PY) -m pytest

docs: $(STAMP)  ## build the documentation site, warnings are errors -> docs/_build/html/index.html
	$(PY) -m sphinx -W --keep-going -b html docs docs/_build/html

lint: $(STAMP)  ## ruff only
	$(VENV)/bin/ruff check observers systems benchmarks tests

bench: $(STAMP)  ## every config (JOBS=N workers, default: the cores; JOBS=1: serial times) -> results/, reports/; speed.md, scaling.md, frontier.md, index.html
	$(PY) -m benchmarks designs $(CONFIGS_ALL) --jobs $(JOBS)
	@rm -f $(RESULTS)/.bench-failed; for cfg in $(CONFIGS_ALL); do \
		name=$$(basename $$cfg .yaml); \
		$(PY) -m benchmarks run $$cfg --out $(RESULTS)/$$name --jobs $(JOBS); rc=$$?; \
		if [ $$rc -ne 0 ]; then echo "$$name: run exit $$rc (see its report)" >> $(RESULTS)/.bench-failed; fi; \
		[ -f $(RESULTS)/$$name/summary.csv ] || continue; \
		$(PY) -m benchmarks report $(RESULTS)/$$name || exit $$?; \
		$(PY) -m benchmarks report $(RESULTS)/$$name --no-figures --out reports/$$name.md || exit $$?; \
	done
	$(PY) -m benchmarks speed
	$(MAKE) scaling
	$(MAKE) frontier
	$(PY) -m benchmarks index reports --committed
	$(PY) -m benchmarks index reports --results $(RESULTS)
	@if [ -f $(RESULTS)/.bench-failed ]; then echo "make bench: configurations with a failing verdict (reports written; exit 1 = a containment violation or a missed consistent state, 3 = a stopped observer, 4 = an inconsistent record):"; cat $(RESULTS)/.bench-failed; exit 1; fi

speed: $(STAMP)  ## time the speed table -> reports/speed.md (compared with reports/speed.json)
	$(PY) -m benchmarks speed

bench-quick: $(STAMP)  ## a small subset (about 1 min of CPU warm, 2 min on the first run): results/quick/index.html (HTML report) and report.md
	$(PY) -m benchmarks run $(CONFIGS_QUICK) --out $(RESULTS)/quick
	$(PY) -m benchmarks report $(RESULTS)/quick

scaling: $(STAMP)  ## scaling study, n-tank up to 200 states -> reports/scaling.md (budgeted)
	$(PY) -m benchmarks.studies.scaling --out reports/scaling.md --results $(RESULTS)/scaling

frontier: $(STAMP)  ## frontier study, gap to the exact floor vs cost of the complexity knobs -> reports/frontier.md (budgeted)
	$(PY) -m benchmarks.studies.frontier --out reports/frontier.md --results $(RESULTS)/frontier

check: $(STAMP)  ## CI gate: committed reports fresh (content hashes), regression subset vs results/baseline/
	$(PY) -m benchmarks check --reports reports

baseline: $(STAMP)  ## rewrite the golden files in results/baseline/ (measures BLAS kernel sensitivity; commit them)
	$(PY) -m benchmarks baseline --update

reports: bench audit  ## regenerate every committed report (bench, audit, data-driven study)
	$(PY) -m benchmarks.studies.alanwar2022 --out reports/datadriven.md

history: $(STAMP)  ## accuracy of the golden summaries over the git history -> results/history/index.html
	$(PY) -m benchmarks history

audit: $(STAMP)  ## soundness audit, 100 realisations per observer and scenario -> reports/soundness.md
	$(PY) -m benchmarks audit

audit-short: $(STAMP)  ## CI: audit on 6 adversarial realisations per scenario -> results/audit-short/
	$(PY) -m benchmarks audit --short --no-progress

report: $(STAMP)  ## (re)write report.md, index.html and figures for every results/<config>/
	@for dir in $(RESULTS)/*/; do \
		[ -f $$dir/summary.csv ] && $(PY) -m benchmarks report $$dir || true; \
	done

clean:  ## remove caches (keeps .venv and results)
	rm -rf .pytest_cache .ruff_cache build *.egg-info docs/_build docs/observers docs/api
