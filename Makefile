# The README's commands. Everything installs from scratch into .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-fast lab bench bench-venv bench-hands results clean browser lint wheel-check export-js docs fuzz

setup: $(STAMP)

# torch first: a bare `torch` requirement resolved by pip may pull a multi-GB GPU build. TORCH_INDEX: an index
# to take it from (https://download.pytorch.org/whl/cpu for a CPU build where PyPI's Linux wheel is CUDA's)
TORCH_INDEX ?=
$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet torch==2.13.0 $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PIP) install --quiet -e ".[lab,test,video,batch,docs]"
	touch $(STAMP)

demo: setup
	$(VENV)/bin/nlo-lab demo

# Tests and every notebook (nbval runs each cell, fails on any error). Test mode
# shortens the notebooks' loops; tests/lab/test_browser.py runs 01 and 05 in JupyterLab + chromium.
test: setup browser export-js lint wheel-check
	NLO_LAB_TEST_MODE=1 $(PY) -m pytest -q -p no:cacheprovider tests notebooks \
		--nbval-lax --nbval-current-env --nbval-cell-timeout=300

# The tests but the slow (marked `slow`) and the real-browser ones (`browser`): a few minutes on
# 2 cores (CONTRIBUTING.md, "Tests"). `make test` runs everything.
test-fast: setup
	NLO_LAB_TEST_MODE=1 $(PY) -m pytest -q -p no:cacheprovider tests -m "not slow and not browser"

# Mutation fuzzing of every reader, grown from tests/fuzz/corpus (tests/fuzz/README.md): FUZZ_SECONDS of
# mutated files (default 600), each read under the memory ceiling (3 GiB of address space) in at most 60 s,
# then every corpus file through nlo-lab under prlimit --as. A 30-second run is part of make test.
fuzz: setup
	NLO_LAB_TEST_MODE=1 nice -n 10 $(PY) tests/fuzz/fuzz.py --seconds $(or $(FUZZ_SECONDS),600) --cli

# ruff and mypy: their rules, exclusions and the list of modules mypy still excuses are in pyproject.toml.
lint: setup
	$(PY) -m ruff check .
	$(PY) -m mypy

# Build the sdist and the wheel, install the wheel into a venv outside the checkout
# (cached in ~/.cache/nlo_lab/wheel-check: torch and friends install once) and use it
# from an empty folder; then the same with every dependency at its lowest allowed
# version (--lowest). tools/wheel_check.py says what it checks.
wheel-check: setup
	$(PY) tools/wheel_check.py
	$(PY) tools/wheel_check.py --lowest

# The browser test needs Debian's chromium; install it when we can (root + apt),
# otherwise that one test says why it skipped.
browser:
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
		apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null 2>&1; } || \
		echo "note: chromium is not installed and could not be; the browser test will be skipped"

# The CDN files an exported notebook loads (html-manager, anywidget, require.js), installed with npm
# into the user cache for tests/viz/test_export_notebook.py; a note (and a skipped test) without npm or registry.
export-js: setup
	$(PY) tools/export_js.py

lab: setup
	$(VENV)/bin/nlo-lab lab

# The gallery: every notebook run (full budgets; QUICK=1: test mode, a few minutes), then a static site in site/
# (mkdocs + mkdocs-jupyter, the docs extra) with README, RESULTS and PAPER; its JavaScript is copied from npm
# packages (tools/export_js.py), so site/index.html opens offline. tools/docs.py says what it does.
docs: setup
	$(PY) tools/docs.py $(if $(QUICK),--quick,)

# Benchmarks print tables; speed.py, quality.py, headroom.py and video.py also rewrite their sections of
# docs/RESULTS.md (quality.py takes about 15 min on 2 cores, headroom.py 3; QUICK=1 for a short run).
bench: setup
	$(PY) benchmarks/fk.py
	$(PY) benchmarks/frechet.py
	$(PY) benchmarks/retarget_speed.py
	$(PY) benchmarks/long_recording.py --robot yumi $(if $(QUICK),--frames 1000 2000,)
	$(PY) benchmarks/panel.py
	$(PY) benchmarks/viewer.py
	$(PY) benchmarks/speed.py --robot yumi
	$(PY) benchmarks/quality.py --robot yumi $(if $(QUICK),--quick --no-write,)
	$(PY) benchmarks/headroom.py --robot yumi $(if $(QUICK),--limit 3 --no-write,)
	$(PY) benchmarks/video.py $(if $(QUICK),--repeats 1 --no-cli --no-write,)
	$(PY) benchmarks/conditioning.py
	$(PY) benchmarks/motion.py $(if $(QUICK),--robots yumi --clips 3 --no-write,)
	$(PY) benchmarks/batch.py $(if $(QUICK),--inputs 10 --iters 10 --no-write,)
	$(MAKE) bench-hands

# The hand benchmark's second environment: dex-retargeting 0.5 needs numpy >= 2, mediapipe (the `video`
# extra, in .venv) numpy < 2. .venv-bench holds CPU torch first, then the package with its `bench` extra
# (dex-retargeting, pinocchio, nlopt); benchmarks/hands.py runs dex-retargeting there as a subprocess.
BENCH_VENV := .venv-bench
BENCH_STAMP := $(BENCH_VENV)/.installed

bench-venv: $(BENCH_STAMP)

$(BENCH_STAMP): pyproject.toml
	test -x $(BENCH_VENV)/bin/python || $(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(BENCH_VENV)/bin/python -m pip install --quiet torch==2.13.0
	$(BENCH_VENV)/bin/python -m pip install --quiet ".[bench]"
	touch $(BENCH_STAMP)

# nlo_lab against dex-retargeting on YuMi's hands (prints tables, rewrites its section of docs/RESULTS.md)
bench-hands: setup bench-venv
	$(PY) benchmarks/hands.py

# Every figure the docs quote, from the code as it is: tools/results.py runs each benchmark, which rewrites its
# sections of docs/RESULTS.md (stamped: commit, machine, load, date). Resumable (a finished step is skipped while
# the code is unchanged; FORCE=1 reruns). QUICK=1: a short run of every step into build/results-quick/RESULTS.md.
# ONLY=a,b runs some steps; `python tools/results.py --list` lists them with their time on an idle machine;
# `--check` names the sections of docs/RESULTS.md without a full stamp (a full run ends with it).
results: setup
	$(PY) tools/results.py $(if $(QUICK),--quick,) $(if $(FORCE),--force,) $(if $(ONLY),--only $(ONLY),)

clean:
	rm -rf $(VENV) $(BENCH_VENV) build site *.egg-info
