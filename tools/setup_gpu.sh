#!/usr/bin/env bash
# ONNX Runtime's GPU build and its CUDA libraries, from PyPI only, for
# `--device cuda` (Linux x86_64, an NVIDIA GPU and driver; run after
# tools/setup.sh).
#
#   bash tools/setup_gpu.sh        # or: make setup-gpu
#   source .deps/gpu.env           # sets ORT_DYLIB_PATH and LD_LIBRARY_PATH
#
# Installs onnxruntime-gpu[cuda,cudnn]==1.31.1 (CUDA 13 runtime, cuBLAS,
# cuFFT, cuRAND, NVRTC and cuDNN 9 wheels) into $DEPS/venv-gpu and writes
# $DEPS/gpu.env. Idempotent. The CPU set-up (.deps/onnxruntime) is left as it
# is: a process uses the GPU build only when ORT_DYLIB_PATH points at it.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DEPS="${SPSLAM_DEPS:-$ROOT/.deps}"
VENV="$DEPS/venv-gpu"
ENV_FILE="$DEPS/gpu.env"
ORT_VERSION="1.31.1"

step() { printf '[setup-gpu] %-12s %s\n' "$1:" "$2"; }
die() { printf '[setup-gpu] ERROR: %s\n' "$*" >&2; exit 1; }

[[ "$(uname -m)" == "x86_64" ]] || die "the onnxruntime-gpu wheels are for x86_64 Linux; this is $(uname -m)"
command -v python3 >/dev/null || die "python3 not found; run tools/setup.sh first"
mkdir -p "$DEPS"
if [[ ! -x "$VENV/bin/python" ]]; then
    python3 -m venv "$VENV" || die "could not create $VENV"
fi
if "$VENV/bin/python" -c "import importlib.metadata as m, sys; sys.exit(m.version('onnxruntime-gpu') != '$ORT_VERSION')" 2>/dev/null; then
    step venv "onnxruntime-gpu $ORT_VERSION present ($VENV)"
else
    step venv "installing onnxruntime-gpu[cuda,cudnn]==$ORT_VERSION (about 2 GB of CUDA wheels)"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q \
        "onnxruntime-gpu[cuda,cudnn]==$ORT_VERSION" \
        || die "pip install onnxruntime-gpu[cuda,cudnn]==$ORT_VERSION failed"
fi

site="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
lib="$site/onnxruntime/capi/libonnxruntime.so.$ORT_VERSION"
[[ -f "$lib" ]] || die "$lib not found in the onnxruntime-gpu wheel"
[[ -f "$site/onnxruntime/capi/libonnxruntime_providers_cuda.so" ]] \
    || die "the wheel has no libonnxruntime_providers_cuda.so"
# The CUDA provider dlopens libcudart, libcublas, libcudnn, ... by name:
# every lib folder of the nvidia-* wheels goes on LD_LIBRARY_PATH.
cuda_dirs="$(find "$site/nvidia" -type d -name lib 2>/dev/null | sort | paste -sd: -)"
[[ -n "$cuda_dirs" ]] || die "no nvidia/*/lib folders under $site; the CUDA wheels did not install"
cat > "$ENV_FILE" <<ENV
# Written by tools/setup_gpu.sh: ONNX Runtime's GPU build and the CUDA libraries.
export ORT_DYLIB_PATH="$lib"
export LD_LIBRARY_PATH="$cuda_dirs\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
ENV
step env "wrote $ENV_FILE (source it, then use --device cuda)"
if command -v nvidia-smi >/dev/null && nvidia-smi -L >/dev/null 2>&1; then
    step gpu "$(nvidia-smi -L | head -n1)"
else
    step gpu "WARNING: nvidia-smi finds no GPU here; --device cuda will fail with a DeviceUnavailable error"
fi
