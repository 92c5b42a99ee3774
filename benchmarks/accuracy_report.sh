#!/usr/bin/env bash
# Regenerate every table and plot of docs/accuracy_and_stability.md (about 20 minutes on two cores):
# the work-precision study, the eye's row of it, the leave-out costs, and the extreme cases (tests).
set -euo pipefail
cd "$(dirname "$0")/.."
run="mpirun --allow-run-as-root --oversubscribe -n 2 .venv/bin/python3"
$run benchmarks/work_precision.py
$run benchmarks/eye_axial_length.py
$run benchmarks/leave_out.py
$run -m pytest -q tests/test_extremes.py
