# The two commands of the README: `make demo` runs the product against the emulator, `make test`
# runs every check. Both install what they need on a fresh Debian machine (run as root there, or
# have the Debian packages below installed already).

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: test demo lint typecheck pytest codegen venv clean system-deps frontend-test frontend-build peers e2e native-tsan

# Debian packages the tests use: tshark reads our captures, chromium runs the browser tests,
# mosquitto is the MQTT broker of the Sparkplug tests (in /usr/sbin, often not on a user's PATH).
# Installed only when missing (needs root, as on a fresh CI machine).
SYSTEM_COMMANDS := tshark:tshark chromium:chromium mosquitto:mosquitto
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

$(STAMP): backend/pyproject.toml $(NATIVE_SOURCES)
	@command -v python3 >/dev/null || { echo "python3 missing: apt-get install -y python3"; exit 1; }
	@python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "Python >= 3.11 needed"; exit 1; }
	@python3 -m venv --help >/dev/null 2>&1 && python3 -c 'import ensurepip' 2>/dev/null \
	  || { apt-get update -qq && apt-get install -y -qq python3-venv; }
	@# Building the pump needs a C compiler, libc's headers and Python's (python3-dev).
	@command -v cc >/dev/null && [ -e /usr/include/stdio.h ] \
	  || { echo "installing Debian packages: gcc libc6-dev"; apt-get update -qq \
	       && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc libc6-dev >/dev/null; }
	@python3 -c 'import os, sys, sysconfig; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
	  || { echo "installing Debian packages: python3-dev"; apt-get update -qq \
	       && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-dev >/dev/null; }
	python3 -m venv $(VENV)
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
$(TSAN_HARNESS): backend/tests/native/tsan_harness.c $(NATIVE_DIR)/cyclic_pump.c $(NATIVE_DIR)/cyclic_pump.h | $(STAMP)
	@mkdir -p $(@D)
	cc -fsanitize=thread -fno-builtin -g -O1 -std=gnu11 -Wall -Wextra -Werror -I$(NATIVE_DIR) \
	  backend/tests/native/tsan_harness.c $(NATIVE_DIR)/cyclic_pump.c -o $@ -lpthread

native-tsan: $(TSAN_HARNESS)
	TSAN_OPTIONS="halt_on_error=1 exitcode=66 io_sync=0" $(TSAN_HARNESS)

lint: $(STAMP)
	cd backend && ../$(BIN)/ruff check . ../bench && ../$(BIN)/ruff format --check . ../bench

typecheck: $(STAMP)
	cd backend && ../$(BIN)/mypy

# pytest exits 5 when it collected nothing: that is a failure here, never a pass.
pytest: $(STAMP) system-deps peers
	cd backend && status=0 && { ../$(BIN)/pytest $(PYTEST_ARGS) || status=$$?; } && \
	  if [ $$status -eq 5 ]; then echo "pytest collected no tests: failing"; fi && exit $$status

test: lint typecheck native-tsan pytest frontend-test e2e

# Independent EtherNet/IP peers from npm (st-ethernet-ip's IO.Scanner) for backend/tests.
PEERS_STAMP := backend/tests/peers/node_modules/.installed-stamp
$(PEERS_STAMP): backend/tests/peers/package-lock.json backend/tests/peers/package.json
	@command -v npm >/dev/null || { echo "npm missing: install Node.js >= 20"; exit 1; }
	cd backend/tests/peers && npm ci --no-audit --no-fund
	touch $@

peers: $(PEERS_STAMP)

# Frontend (Node >= 20.19 and npm): `npm ci` whenever package-lock.json is newer than the install.
FRONTEND_STAMP := frontend/node_modules/.installed-stamp
$(FRONTEND_STAMP): frontend/package-lock.json frontend/package.json
	@command -v npm >/dev/null || { echo "npm missing: install Node.js >= 20.19"; exit 1; }
	cd frontend && npm ci --no-audit --no-fund
	touch $@

frontend-test: $(FRONTEND_STAMP)
	cd frontend && npm run --silent typecheck && npm run --silent lint && npm test

frontend-build: $(FRONTEND_STAMP)
	cd frontend && npm run build

# The built frontend the service serves: rebuilt when a source is newer than the build.
FRONTEND_DIST := frontend/dist/index.html
$(FRONTEND_DIST): $(FRONTEND_STAMP) frontend/index.html frontend/vite.config.ts frontend/tsconfig.json \
    $(shell find frontend/src -type f 2>/dev/null)
	cd frontend && npm run build

# End to end (e2e/): Playwright with Debian's Chromium (never a downloaded browser) against the
# real emulator and service, which its webServer starts on loopback. E2E_ARGS narrows the run.
E2E_STAMP := e2e/node_modules/.installed-stamp
$(E2E_STAMP): e2e/package-lock.json e2e/package.json
	@command -v npm >/dev/null || { echo "npm missing: install Node.js >= 20.19"; exit 1; }
	cd e2e && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund
	touch $@

e2e: $(STAMP) system-deps $(FRONTEND_DIST) $(E2E_STAMP)
	cd e2e && npm run --silent typecheck && npx playwright test $(E2E_ARGS)

# Everything derived: from the layout (codec, layout.json, layout.ts, docs/assembly.md), the
# service's OpenAPI document (docs/openapi.json), and the frontend's API types from that
# document (frontend/src/generated/api.ts, openapi-typescript). Tests fail on a stale one.
codegen: $(STAMP) $(FRONTEND_STAMP)
	$(BIN)/cobot-hmi codegen
	$(BIN)/cobot-hmi openapi --output docs/openapi.json
	cd frontend && npm run --silent codegen

# The emulator at 127.0.0.2 and the service on http://127.0.0.1:8000 serving the built frontend
# (built first, through npm ci, when the frontend exists); Ctrl-C stops both.
demo: $(STAMP) $(if $(wildcard frontend/package.json),$(FRONTEND_DIST))
	$(BIN)/cobot-hmi demo

clean:
	rm -rf $(VENV) backend/.pytest_cache backend/.mypy_cache backend/.ruff_cache
