# make demo | make test | make test-fast | make bench | make lint (make pytest: the tests alone)
# Each target bootstraps .venv on first use. With a sourced ROS 2 install ($ROS_DISTRO set) the
# venv sees the system packages and the ROS wheels are not installed; otherwise the pinned Jazzy
# wheels come from PyPI through the `ros` extra.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tcomp-installed
OUT ?= out

# Bytecode written even where the environment says not to (PYTHONDONTWRITEBYTECODE=1, empty
# counts as unset): every process of every target would otherwise compile what it imports from
# source, and pytest rewrite every test module's assertions in each of its processes, on every
# run (py-spy: about 11 CPU-seconds a run of the tests; make test 293.3 -> 290.9 s side by
# side). The caches go to __pycache__/, which git ignores.
export PYTHONDONTWRITEBYTECODE :=

ifdef ROS_DISTRO
VENV_FLAGS := --system-site-packages
EXTRAS := test
else
VENV_FLAGS :=
EXTRAS := ros,test
endif

.PHONY: demo test pytest test-fast bench lint clean

# uv installs the same pinned packages as pip in half the time (on a fresh 2-core machine, no
# caches: 25 s against 46 s). It trusts the system's certificates and pip's local wheel
# directories as pip does here (PIP_CERT, PIP_FIND_LINKS); where uv cannot be installed or
# cannot install the venv, pip does it. Neither compiles the venv's bytecode at install: the
# first process that imports a module compiles it (every target here lets Python write its
# caches, above), and the modules the package imports cost less than the whole venv's (CI's
# command on fresh clones, alternating: 337.8 against 344.6 s and 317.1 against 329.0 s
# without it, the tests themselves no slower).
# The venv is made without pip (ensurepip's copy of it costs 3.4 s of a fresh machine's 2-core
# bootstrap): the system's pip installs uv into it, and where there is none, or uv fails, the
# venv gets pip of its own and pip installs everything.
UV_FIND_LINKS := $(foreach links,$(PIP_FIND_LINKS),--find-links $(links))
$(STAMP): setup.py setup.cfg package.xml
	$(PYTHON) -m venv --without-pip $(VENV_FLAGS) $(VENV)
	if $(PYTHON) -m pip --python $(PY) install --quiet --disable-pip-version-check uv && \
		$(PY) -m uv pip install --quiet --native-tls --python $(PY) \
			$(UV_FIND_LINKS) -e '.[$(EXTRAS)]'; then :; else \
		echo "uv did not install the venv: pip installs it"; \
		$(PY) -m ensurepip --upgrade --default-pip >/dev/null && \
		$(PY) -m pip install --quiet --upgrade pip && \
			$(PY) -m pip install --quiet --no-compile -e '.[$(EXTRAS)]'; \
	fi
	touch $(STAMP)

# Everything: all tests and the static checks (ruff, mypy). One BLAS thread per test process:
# the processes already fill the cores. The static checks run beside the tests instead of after
# them, at the lowest priority (nice 19, below the tests' 10 and 0), so they take a small share
# of the busy machine (mypy without its cache, as on a fresh machine: 17 s of CPU); their output
# follows pytest's, and either failing fails the target.
test: $(STAMP)
	@lint_log=$$(mktemp); \
	nice -n 19 $(MAKE) --no-print-directory lint >"$$lint_log" 2>&1 & lint_pid=$$!; \
	$(MAKE) --no-print-directory pytest; tests=$$?; \
	wait $$lint_pid; lint=$$?; \
	echo; echo "== static checks (make lint), run beside the tests: exit $$lint =="; \
	cat "$$lint_log"; rm -f "$$lint_log"; \
	test $$tests -eq 0 && test $$lint -eq 0

# The tests in two pytest runs at once. The tests that keep to the wall clock (marker realtime:
# ROS nodes over DDS, a Dask cluster, background workers) run one at a time, each ROS test on
# its own domain (test/ros/conftest.py). The rest run on every core (pytest-xdist) beside them
# at a lower priority: they take the cycles the real-time tests leave while those wait on
# messages (two workers for everything left a core idle 7 % of the run), and never crowd them
# (their timing failed under three equal workers on two cores). The real-time run's output
# follows the other's; either failing, or collecting no test, fails the target.
# PYTEST_WORKERS=1 runs the rest one at a time too.
PYTEST_WORKERS ?= auto
PYTEST_FLAGS ?= --durations=20
PARALLEL := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
PYTEST_REST := $(PARALLEL) nice -n 10 $(PY) -m pytest $(PYTEST_FLAGS) \
	-n $(PYTEST_WORKERS) --dist worksteal -m 'not realtime'
PYTEST_REALTIME := $(PARALLEL) $(PY) -m pytest $(PYTEST_FLAGS) -m realtime \
	-o cache_dir=.pytest_cache/realtime
pytest: $(STAMP)
	@realtime_log=$$(mktemp); \
	$(PYTEST_REALTIME) >"$$realtime_log" 2>&1 & realtime_pid=$$!; \
	echo "$(PYTEST_REST)"; $(PYTEST_REST); rest=$$?; \
	wait $$realtime_pid; realtime=$$?; \
	echo; echo "== the real-time tests, run beside: $(PYTEST_REALTIME): exit $$realtime =="; \
	cat "$$realtime_log"; rm -f "$$realtime_log"; \
	test $$rest -eq 0 && test $$realtime -eq 0

# The edit-test loop: the tests not marked slow (see the markers in pyproject.toml).
test-fast: $(STAMP)
	$(PARALLEL) $(PY) -m pytest -n $(PYTEST_WORKERS) --dist worksteal -m "not slow"

demo: $(STAMP)
	$(PY) -m tcomp_core.demo --out $(OUT)/demo
	@echo
	@echo "== ROS 2: replay bags/rig_sine_5khz (5 kHz) into the compensator node, half speed =="
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-42} $(PY) -m tcomp_ros.demo --bag bags/rig_sine_5khz --rate 0.5 \
		--ros-args --params-file config/compensator.yaml
	@echo
	@echo "== ROS 2: replay bags/conduction_500hz (hidden conduction) with compensate_effects =="
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-42} $(PY) -m tcomp_ros.demo --bag bags/conduction_500hz \
		--ros-args --params-file config/compensator.yaml \
		-p effects:=auto -p compensate_effects:=true -p diagnosis_period_s:=5.0

bench: $(STAMP)
	$(PY) bench/bench_startup.py
	$(PY) bench/bench_worker_start.py
	$(PY) bench/bench_bag_open.py
	$(PY) bench/bench_scatter_vs_svd.py
	$(PY) bench/bench_accuracy.py
	$(PY) bench/bench_reconstruction.py
	$(PY) bench/bench_diagnose.py
	$(PY) bench/bench_process.py
	$(PY) bench/bench_window_estimate.py --repeat 3
	$(PY) bench/bench_realtime.py

lint: $(STAMP)
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .
	$(PY) -m mypy

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info
