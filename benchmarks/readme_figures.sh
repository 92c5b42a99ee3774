#!/usr/bin/env bash
# Reproduce the README's default-eye figures (tests/test_readme_figures.py, marked slow: about
# 2 minutes on two cores). CI runs the fast suite only; run this before quoting a new figure.
set -euo pipefail
cd "$(dirname "$0")/.."
mpirun --allow-run-as-root --oversubscribe -n 2 .venv/bin/python3 -m pytest -q -o faulthandler_timeout=0 -m slow tests/test_readme_figures.py
