#!/usr/bin/env bash
# Set up everything on a Debian 12 machine (run as root, or with sudo available):
# Debian's FEniCSx stack, a fast BLAS, and this package in .venv (a venv that sees the
# system packages). Quick when everything is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
packages=(python3-dolfinx-real python3-gmsh python3-pytest python3-matplotlib python3-scipy python3-tomli-w
          python3-venv libopenblas0-serial openmpi-bin)
if ! dpkg -s "${packages[@]}" >/dev/null 2>&1; then
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing Debian packages: ${packages[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${packages[@]}" >/dev/null
fi
if [ ! -x .venv/bin/eyeball-fenicsx ]; then
  echo "setup: installing eyeball-fenicsx into .venv"
  /usr/bin/python3 -m venv --system-site-packages .venv
  .venv/bin/python3 -m pip install -q --no-build-isolation --no-deps -e .
fi
if [ ! -x .venv/bin/ruff ]; then  # the linter .ci/run runs (configured in pyproject.toml)
  echo "setup: installing ruff into .venv"
  .venv/bin/python3 -m pip install -q ruff==0.8.6
fi
