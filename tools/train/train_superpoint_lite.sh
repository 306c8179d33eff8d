#!/usr/bin/env bash
# SuperPoint-Lite, distilled from the photo model: `make train-superpoint-lite` runs this.
#
#   bash tools/train/train_superpoint_lite.sh            # cuda when PyTorch sees a GPU, else cpu
#   SPSLAM_TRAIN_DEVICE=cpu bash tools/train/train_superpoint_lite.sh
#
# Stages (each skipped when its output exists; the distillation resumes from its checkpoint):
#   1. prepare  the photographs of $SPSLAM_DATA/train_images: gray, long side <= 640 (cpu: 400)
#   2. distill  distill.py: teacher models/superpoint_photo.pth, student widths 16,32,64,64 head 128
#               (the first stage runs at full resolution and sets the int8 time; see tools/train/README.md)
#   3. finish   finish_model.sh: superpoint_lite{,_int8,_int8_avx2}.onnx, the matcher's thresholds and
#               the grid artefact into the sidecar, the sha256s
#
# Sizes per device:
#   cuda: batch 64, 4300 steps (on one H200 about 150 ms per step: 11 min);
#   cpu:  batch 8, 4000 steps (about 1.6 s per step on 2 cores: 1.8 hours); a smaller run than the GPU's.
# SPSLAM_TRAIN_BUDGET=SECONDS stops the distillation cleanly after that long (run again to resume).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
DATA="${SPSLAM_DATA:-$ROOT/../shared/data}"
WORK="${SPSLAM_TRAIN_WORK:-$ROOT/.train_cache}"
OUT_DIR="${SPSLAM_TRAIN_OUT:-$WORK/out}"
PY="${SPSLAM_TRAIN_PYTHON:-$ROOT/.deps/venv-train/bin/python}"
TEACHER="${SPSLAM_LITE_TEACHER:-$ROOT/models/superpoint_photo.pth}"
T="$ROOT/tools/train"

step() { printf '[train-superpoint-lite] %-8s %s\n' "$1:" "$2"; }
die() { printf '[train-superpoint-lite] ERROR: %s\n' "$*" >&2; exit 1; }

[[ -x "$PY" ]] || die "$PY not found: run 'make train-superpoint-lite' (it installs tools/train/requirements.txt)"
[[ -f "$TEACHER" ]] || die "teacher $TEACHER not found"
[[ -d "$DATA/train_images" ]] || die "no training photographs at $DATA/train_images (set SPSLAM_DATA)"
DEVICE="${SPSLAM_TRAIN_DEVICE:-$("$PY" -c 'import torch; print("cuda" if torch.cuda.is_available() else "cpu")')}"
if [[ "$DEVICE" == cuda ]]; then
    MAX_SIDE=640; BATCH=64; STEPS=4300
else
    MAX_SIDE=400; BATCH=8; STEPS=4000
fi
step device "$DEVICE (images <= $MAX_SIDE px, batch $BATCH, $STEPS steps)"
mkdir -p "$WORK" "$OUT_DIR"
IMAGES="$WORK/images_$MAX_SIDE"
if [[ ! -f "$IMAGES/index.tsv" ]]; then
    step prepare "$DATA/train_images -> $IMAGES"
    "$PY" "$T/prepare_images.py" --src "$DATA/train_images" --out "$IMAGES" --max-side "$MAX_SIDE" --quality 85
fi
RUN="$WORK/lite_$DEVICE"
if [[ ! -f "$RUN/run.json" ]] || ! grep -q '"complete": true' "$RUN/run.json"; then
    step distill "$STEPS steps -> $RUN"
    "$PY" "$T/distill.py" --images "$IMAGES" --teacher "$TEACHER" --student superpoint_lite=16,32,64,64,128 \
        --out "$RUN" --steps "$STEPS" --batch "$BATCH" --device "$DEVICE" --time-budget "${SPSLAM_TRAIN_BUDGET:-0}"
    if ! grep -q '"complete": true' "$RUN/run.json"; then
        step stopped "the time budget ended the distillation; run the same command again to resume"
        exit 0
    fi
fi
cp "$RUN/superpoint_lite.pth" "$RUN/superpoint_lite.pth.provenance.json" "$OUT_DIR/"
bash "$T/finish_model.sh" "$OUT_DIR" superpoint_lite
step done "compare it with tools/compare_models.sh (see tools/train/README.md)"
