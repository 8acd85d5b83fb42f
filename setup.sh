#!/usr/bin/env bash
# Set up a fresh Debian/Ubuntu machine for the runtime: system libraries, a Python 3.11 venv in .venv, and the
# pinned Python packages. Idempotent: a second run only re-installs when pyproject.toml changed.
set -euo pipefail
cd "$(dirname "$0")"

# libusb: open3d and the Orbbec SDK; EGL + Mesa or OSMesa: headless MuJoCo rendering; chromium: console tests.
APT_PACKAGES=(libusb-1.0-0 libegl1 libgl1-mesa-dri libosmesa6 chromium)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if ((${#missing[@]})); then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
    sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "setup: missing system packages: ${missing[*]}" >&2
    echo "setup: install them with: sudo apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
fi

PYTHON=${PYTHON:-}
for candidate in python3.11 python3; do
  [ -n "$PYTHON" ] && break
  command -v "$candidate" >/dev/null && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
    && PYTHON=$candidate
done
if [ -z "$PYTHON" ]; then
  echo "setup: Python 3.11 is required (the pinned wheels are built for it); set PYTHON=/path/to/python3.11" >&2
  exit 1
fi
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv

NEED_MB=${NEED_MB:-5120}
stamp=.venv/.setup-stamp
want=$(sha256sum pyproject.toml setup.sh | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  # a first install takes about 4 GB (torch, Open3D, Pinocchio, Rerun, Ray): say so rather than fail in pip's OSError
  free_mb=$(df -Pm . | awk 'NR == 2 {print $4}')
  if [ ! -e "$stamp" ] && [ "${free_mb:-0}" -lt "$NEED_MB" ]; then
    echo "setup: ${free_mb} MB free on $(pwd); a first install needs about ${NEED_MB} MB: free some space" \
      "(NEED_MB=0 bash setup.sh tries anyway)" >&2
    exit 1
  fi
  echo "setup: installing Python packages into .venv (about 2 minutes the first time; log: .venv/setup.log)"
  {
    .venv/bin/pip install --upgrade pip &&
      .venv/bin/pip install -e '.[dev]' &&
      # pyorbbecsdk2's metadata pins numpy<2 and open3d 0.18; without --no-deps it would break the environment.
      .venv/bin/pip install --no-deps pyorbbecsdk2==2.1.2
  } >.venv/setup.log 2>&1 || { tail -n 40 .venv/setup.log >&2; echo "setup: pip failed (see .venv/setup.log)" >&2; exit 1; }
  echo "$want" >"$stamp"
fi
echo "setup: ready (.venv)"
