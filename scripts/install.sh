#!/usr/bin/env bash
# Install everything sonarcal needs on a fresh Debian machine with Python 3.11.
# Idempotent and quiet: a second run does nothing and prints nothing.
set -euo pipefail
cd "$(dirname "$0")/.."

# System libraries open3d links against, and Debian's Chromium for the browser tests.
apt_pkgs=(chromium libusb-1.0-0 libegl1 libgl1 libglx0 libglvnd0 libx11-6 libxcb1 libudev1 libgomp1)
missing=()
for p in "${apt_pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  echo "installing system packages: ${missing[*]}"
  $SUDO apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
[ -x .venv/bin/python ] || "$PY" -m venv .venv
stamp=".venv/.installed-$(cat pyproject.toml scripts/constraints.txt | sha1sum | cut -c1-12)"
if [ ! -f "$stamp" ]; then
  echo "installing Python packages into .venv (first run takes about a minute)"
  if ! .venv/bin/python -m pip install -q --disable-pip-version-check -c scripts/constraints.txt -e '.[test]' > .venv/pip.log 2>&1; then
    grep -v "is ignored" .venv/pip.log >&2; exit 1
  fi
  rm -f .venv/.installed-*; touch "$stamp"
fi
