# mjnav: two commands for a fresh Debian machine with Python >= 3.11.
#   make demo   set up, then run the product
#   make test   set up, then lint, type-check and run every test
# Set-up is idempotent: .venv is created or updated when pyproject.toml changes, numba kernels are compiled into
# their caches (mjnav warmup), and the Debian packages
# needed for offscreen rendering are installed when missing (apt-get as root; otherwise the names are printed).

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.mjnav-installed
# Offscreen rendering for MuJoCo: EGL (Mesa, software) or OSMesa. SuiteSparse headers: scikit-sparse (CHOLMOD,
# the pose graph's sparse Cholesky) builds against them.
SYSTEM_PACKAGES := libegl1 libgl1-mesa-dri libosmesa6 libsuitesparse-dev
# Only the tests need these: headless Chromium (browser check of the viz snapshot) and docker-compose (validates
# docker/compose.yaml), geographiclib-tools (CartConvert: fresh geodetic reference points). Without them those
# tests skip and say why.
TEST_PACKAGES := chromium docker-compose geographiclib-tools
# apt_get (what every apt-get call here goes through) waits at most APT_LOCK_WAIT_S for a lock another apt or dpkg
# process holds (unattended-upgrades, another make) and says so, instead of failing with "Could not get lock": each
# try waits inside apt-get for the dpkg lock (-o DPkg::Lock::Timeout), and a try that still finds a lock held (also
# the package lists' lock of apt-get update, which that option does not cover) is repeated every 5 s.
APT_LOCK_WAIT_S ?= 300
DEFINE_APT_GET = apt_get() { \
    local deadline=$$((SECONDS + $(APT_LOCK_WAIT_S))) out lock said=; \
    until out=$$(LC_ALL=C apt-get -o DPkg::Lock::Timeout=5 "$$@" 2>&1); do \
      lock=$$(grep -m1 -E 'Could not get lock|Unable to acquire the dpkg' <<<"$$out") && [ $$SECONDS -lt $$deadline ] \
        || { echo "$$out" >&2; return 1; }; \
      [ -n "$$said" ] || echo "apt-get $$1: waiting up to $(APT_LOCK_WAIT_S) s for another apt process ($${lock:3})"; \
      said=1; sleep 5; \
    done; \
    [ -z "$$out" ] || echo "$$out"; \
  }
DEMO_WORLD ?= rooms
DEMO_RTF ?= 2
PYTEST_ARGS ?=

.PHONY: demo test setup warmup system-deps test-deps lint bench lock clean

# The mission: the robot maps the world from scratch and drives to its goal; video, map and summary in runs/.
demo: setup
	@out=runs/$$(date +%Y%m%d-%H%M%S); \
	$(BIN)/mjnav demo --world $(DEMO_WORLD) --rtf $(DEMO_RTF) --record --headless --out $$out; code=$$?; \
	echo "make demo: video, map and summary in $$out/"; exit $$code

test: lint test-deps
	$(BIN)/pytest $(PYTEST_ARGS)

lint: setup
	$(BIN)/ruff check mjnav tests benchmarks examples
	$(BIN)/ruff format --check mjnav tests benchmarks examples
	$(BIN)/mypy mjnav examples

setup: system-deps $(STAMP) warmup

# numba caches: every kernel compiled once here (a few minutes on a fresh install, seconds afterwards; a kernel whose
# module changed is compiled again), so no service compiles while the stack starts.
warmup: $(STAMP)
	$(BIN)/mjnav warmup --quiet

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' || \
	  { echo "mjnav needs Python >= 3.11; $(PYTHON) is $$($(PYTHON) --version 2>&1). Use make PYTHON=python3.11"; exit 1; }
	@if [ ! -x $(BIN)/python ]; then \
	  $(PYTHON) -m venv $(VENV) 2>/dev/null || { \
	    rm -rf $(VENV); \
	    if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	      $(DEFINE_APT_GET); apt_get update -qq && DEBIAN_FRONTEND=noninteractive apt_get install -y -qq python3-venv && $(PYTHON) -m venv $(VENV); \
	    else echo "cannot create a virtual environment: install the Debian package python3-venv"; exit 1; fi; }; \
	fi
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,bench,foxglove,plot]'
	@touch $(STAMP)

system-deps:
	@if ! command -v dpkg >/dev/null; then echo "not a Debian system: make sure EGL or OSMesa is installed for rendering"; exit 0; fi; \
	missing=""; for p in $(SYSTEM_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  echo "installing Debian packages:$$missing"; \
	  $(DEFINE_APT_GET); apt_get update -qq && DEBIAN_FRONTEND=noninteractive apt_get install -y -qq --no-install-recommends $$missing; \
	else \
	  echo "WARNING: offscreen rendering needs the Debian packages:$$missing"; \
	  echo "         install them with: sudo apt-get install$$missing (rendering tests skip until then)"; \
	fi

test-deps:
	@if ! command -v dpkg >/dev/null; then echo "not a Debian system: install chromium and docker-compose for the browser and compose checks"; exit 0; fi; \
	missing=""; for p in $(TEST_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  echo "installing Debian packages for the tests:$$missing"; \
	  $(DEFINE_APT_GET); apt_get update -qq && DEBIAN_FRONTEND=noninteractive apt_get install -y -qq --no-install-recommends $$missing; \
	else \
	  echo "NOTE: without$$missing the browser check and compose validation skip (sudo apt-get install$$missing)"; \
	fi

# docker/requirements.txt: the image's pinned packages, resolved afresh in a scratch virtual environment from
# pyproject.toml's dependencies and the foxglove extra.
lock:
	@tmp=$$(mktemp -d); $(PYTHON) -m venv $$tmp/venv && $$tmp/venv/bin/pip install --quiet --upgrade pip && \
	  $$tmp/venv/bin/pip install --quiet '.[foxglove]' && \
	  { sed -n '/^#/p' docker/requirements.txt; $$tmp/venv/bin/pip freeze --exclude mjnav; } > $$tmp/requirements.txt && \
	  mv $$tmp/requirements.txt docker/requirements.txt; rm -rf $$tmp; echo "wrote docker/requirements.txt"

bench: setup
	@for b in benchmarks/*.py; do echo "== $$b"; $(BIN)/python $$b --quick || exit 1; done

clean:
	rm -rf $(VENV) .mypy_cache .ruff_cache .pytest_cache
