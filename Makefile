# Quick start: `make run` (service with demo data) and `make test` (whole suite).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
HOST ?= 127.0.0.1:8000
# Installing needs only pip (every package pinned with its hashes in the lock files);
# compiling the lock files (`make lock`) needs uv, installed into the venv at this version.
PIP_VERSION := 26.3
UV_VERSION := 0.13.9
LOCK_PLATFORM := --python-version 3.11 --python-platform x86_64-unknown-linux-gnu
UV_COMPILE = $(VENV)/bin/uv pip compile --quiet --generate-hashes $(LOCK_PLATFORM) \
	--custom-compile-command "make lock" $(LOCK_FLAGS)

.PHONY: run serve test lint format migrate demo bench lock lock-upgrade clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet pip==$(PIP_VERSION)

# The venv is brought to the lock whenever the lock file is newer than the stamp.
$(VENV)/.runtime: requirements.lock | $(PY)
	$(PY) -m pip install --quiet --require-hashes -r requirements.lock
	touch $@

$(VENV)/.dev: requirements-dev.lock | $(PY)
	$(PY) -m pip install --quiet --require-hashes -r requirements-dev.lock
	touch $@ $(VENV)/.runtime

$(VENV)/bin/uv: | $(PY)
	$(PY) -m pip install --quiet uv==$(UV_VERSION)

# After editing requirements.txt or requirements-dev.txt (the ranges): re-resolve, keeping
# the current pins where the ranges still allow them; `make lock-upgrade` takes the newest.
# The dev lock is constrained by the runtime lock, so both pin the same runtime versions.
lock: $(VENV)/bin/uv
	$(UV_COMPILE) requirements.txt -o requirements.lock
	$(UV_COMPILE) requirements-dev.txt -c requirements.lock -o requirements-dev.lock

lock-upgrade:
	$(MAKE) lock LOCK_FLAGS=--upgrade

migrate: $(VENV)/.runtime
	$(PY) manage.py migrate --noinput

demo: migrate
	$(PY) manage.py load_demo

run: demo
	@echo "Serving on http://$(HOST)/  (admin: http://$(HOST)/admin/)"
	$(PY) manage.py runserver $(HOST)

# Production mode on one machine: gunicorn + Celery worker + Celery beat (deploy/serve.py),
# after migrate, collectstatic and check --deploy. Needs SECRET_KEY, DATABASE_URL (PostgreSQL)
# and CELERY_BROKER_URL, from the environment or ENV_FILE=path (deploy/env.example). Ctrl-C stops all.
serve: $(VENV)/.runtime
	$(PY) deploy/serve.py

test: $(VENV)/.dev
	$(PY) -m pytest -n 2

lint: $(VENV)/.dev
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/lint-imports --no-cache

format: $(VENV)/.dev
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

bench: $(VENV)/.dev
	$(PY) bench/bench_core.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .mypy_cache .hypothesis
