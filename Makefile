# The two commands of the README: `make demo` runs the product against the emulator, `make test`
# runs every check. Both install what they need on a fresh Debian machine (run as root there, or
# have the Debian packages below installed already).

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: test demo lint typecheck pytest codegen venv clean system-deps frontend-test frontend-build peers e2e

# Debian packages the tests use: tshark reads our captures, chromium runs the browser tests.
# Installed only when missing (needs root, as on a fresh CI machine).
SYSTEM_COMMANDS := tshark:tshark chromium:chromium
system-deps:
	@missing=""; for pair in $(SYSTEM_COMMANDS); do \
	  command -v "$${pair%%:*}" >/dev/null || missing="$$missing $${pair##*:}"; done; \
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

$(STAMP): backend/pyproject.toml
	@command -v python3 >/dev/null || { echo "python3 missing: apt-get install -y python3"; exit 1; }
	@python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "Python >= 3.11 needed"; exit 1; }
	@python3 -m venv --help >/dev/null 2>&1 && python3 -c 'import ensurepip' 2>/dev/null \
	  || { apt-get update -qq && apt-get install -y -qq python3-venv; }
	python3 -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e 'backend[dev]'
	@# The cyclic pump (backend/src/cobot_hmi/native) is C, loaded with ctypes: a compiler and
	@# libc's headers build it (Python's headers are not needed).
	@command -v cc >/dev/null && [ -e /usr/include/stdio.h ] \
	  || { echo "installing Debian packages: gcc libc6-dev"; apt-get update -qq \
	       && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc libc6-dev >/dev/null; }
	$(PY) -m cobot_hmi.native
	touch $@

lint: $(STAMP)
	cd backend && ../$(BIN)/ruff check . ../bench && ../$(BIN)/ruff format --check . ../bench

typecheck: $(STAMP)
	cd backend && ../$(BIN)/mypy

# pytest exits 5 when it collected nothing: that is a failure here, never a pass.
pytest: $(STAMP) system-deps peers
	cd backend && status=0 && { ../$(BIN)/pytest $(PYTEST_ARGS) || status=$$?; } && \
	  if [ $$status -eq 5 ]; then echo "pytest collected no tests: failing"; fi && exit $$status

test: lint typecheck pytest frontend-test e2e

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
	cd frontend && npm run --silent typecheck && npm test

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

codegen: $(STAMP)
	$(BIN)/cobot-hmi codegen

# The emulator at 127.0.0.2 and the service on http://127.0.0.1:8000 serving the built frontend
# (built first, through npm ci, when the frontend exists); Ctrl-C stops both.
demo: $(STAMP) $(if $(wildcard frontend/package.json),$(FRONTEND_DIST))
	$(BIN)/cobot-hmi demo

clean:
	rm -rf $(VENV) backend/.pytest_cache backend/.mypy_cache backend/.ruff_cache
