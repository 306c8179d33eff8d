#!/usr/bin/env bash
# Packs `make gpu-check` for an x86-64 NVIDIA machine that has no network and
# takes uploads in pieces (the H200 lent to sessions here: 64 MiB a call, the
# repository's ~12 MiB included). See README.md beside this file.
#
#   bash tools/gpu_check_offline/pack.sh [OUT_DIR]     # default .gpurun
#
# Writes OUT_DIR/c1 (ONNX Runtime's CUDA provider with only sm_90 code, ~50
# MiB), OUT_DIR/c2 (the rest: ONNX Runtime's GPU core library, gpu_check, the
# OpenCV core/imgproc/flann closure, the models, a KITTI frame as PGM and the
# device-side script) and, for GPUs other than sm_90, OUT_DIR/c3.. (the other
# architectures' code, ~45 MiB each). Needs `make setup` done and the data.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
OUT="$(realpath -m "${1:-$ROOT/.gpurun}")"
DATA="${SPSLAM_DATA:-$ROOT/../shared/data}"
ORT_VERSION=1.31.1
KEEP_SM=90
WORK="$(mktemp -d)"; trap 'rm -rf "$WORK"' EXIT
step() { printf '[gpu-pack] %s\n' "$*"; }

rm -rf "$OUT"; mkdir -p "$OUT/c1" "$OUT/c2" "$WORK/bundle/cv" "$WORK/bundle/models"
step "onnxruntime-gpu $ORT_VERSION from PyPI"
python3 -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: \
    --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64 \
    -d "$WORK" "onnxruntime-gpu==$ORT_VERSION"
(cd "$WORK" && unzip -q -o onnxruntime_gpu-*.whl 'onnxruntime/capi/*.so*')
capi="$WORK/onnxruntime/capi"
step "keeping sm_$KEEP_SM code in the CUDA provider; the rest goes to c3.."
python3 "$HERE/fatbin_split.py" split "$capi/libonnxruntime_providers_cuda.so" $KEEP_SM "$WORK/zeroed.so" "$WORK/rest.bin"
xz -9 -T2 -c "$WORK/zeroed.so" > "$OUT/c1/zeroed.xz"
xz -9 -T2 -c "$WORK/rest.bin" | split -b 45M -d - "$WORK/rest.xz.part"
i=3; for part in "$WORK"/rest.xz.part*; do mkdir -p "$OUT/c$i"; mv "$part" "$OUT/c$i/"; i=$((i + 1)); done
xz -9 -T2 -c "$capi/libonnxruntime.so.$ORT_VERSION" > "$OUT/c2/core.xz"
cp "$capi/libonnxruntime_providers_shared.so" "$OUT/c2/shared.so"

step "gpu_check and the OpenCV libraries it needs"
(cd "$ROOT" && cargo build --release --example gpu_check)
strip -o "$WORK/bundle/gpu_check" "$ROOT/target/release/examples/gpu_check"
# gpu_check reads a PGM itself; cv::imread, its one use of OpenCV's codecs
# (whose closure is 178 MB with GDAL), is a stub that aborts.
cat > "$WORK/stub.c" <<'C'
#include <stdio.h>
#include <stdlib.h>
void _ZN2cv6imreadERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEi(void) { fputs("cv::imread is not carried\n", stderr); abort(); }
C
gcc -shared -fPIC -O2 -Wl,-soname,libopencv_imgcodecs.so.406 -o "$WORK/bundle/cv/libopencv_imgcodecs.so.406" "$WORK/stub.c"
for module in core imgproc flann; do
    lib="/lib/x86_64-linux-gnu/libopencv_$module.so.406"
    { echo "$lib"; ldd "$lib" | awk '{print $3}'; }
done | grep '^/' | sort -u \
    | grep -v -E '/(libc|libm|libdl|libpthread|librt|libstdc\+\+|libgcc_s|ld-linux)[.-]' \
    | while read -r lib; do cp -L "$lib" "$WORK/bundle/cv/"; done
cp "$ROOT"/models/superpoint*.onnx "$WORK/bundle/models/"
# Pillow from make setup's .deps/venv writes the frame as a binary PGM.
"$ROOT/.deps/venv/bin/python" -c 'import sys; from PIL import Image; Image.open(sys.argv[1]).convert("L").save(sys.argv[2])' \
    "$DATA/kitti/sequences/06/image_0/000000.png" "$WORK/bundle/kitti06_000000.pgm"
tar -C "$WORK/bundle" -cf - . | xz -6 -T2 > "$OUT/c2/bundle.tar.xz"
cp "$HERE/run_on_device.sh" "$HERE/fatbin_split.py" "$OUT/c2/"
du -sh "$OUT"/c*
step "done: carry $OUT/c1, then $OUT/c2 (README.md beside this script)"
