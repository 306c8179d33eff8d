#!/usr/bin/env bash
# Compare a candidate SuperPoint state dict with the shipped model on this CPU, as markdown:
# the homography benchmark (held-out photographs from scikit-image's data, and the shared
# excerpts' frames), the stereo same-row fraction on KITTI 06 and rectified EuRoC, and the periodic artefact on
# flat dark noise without the filter. Writes the report to stdout.
#
#   bash tools/compare_models.sh models/superpoint_photo.pth > report.md
#   bash tools/compare_models.sh models/superpoint_lite.pth models/superpoint_photo.pth   # against a baseline
#
# The baseline is the shipped model unless a second state dict is given (quantised the same way).
#
# Needs `make setup` and a release build. The held-out photographs are the 13 photographs
# bundled in the scikit-image 0.25.2 wheel (PyPI), downloaded once into .deps/heldout.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
W="${1:?usage: compare_models.sh CANDIDATE.pth [BASELINE.pth]}"
B="${2:-}"
DATA="${SPSLAM_DATA:-$ROOT/../shared/data}"
PY=.deps/venv/bin/python
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
HELD=.deps/heldout
if [[ ! -f "$HELD/photos/astronaut.png" ]]; then
    mkdir -p "$HELD/photos"
    python3 -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: \
        --python-version 3.11 --platform manylinux2014_x86_64 scikit-image==0.25.2 -d "$HELD" >&2
    (cd "$HELD" && "$ROOT/$PY" -c "
import zipfile, glob
z = zipfile.ZipFile(glob.glob('scikit_image-0.25.2-*.whl')[0])
for n in ['astronaut.png','camera.png','coffee.png','chelsea.png','motorcycle_left.png','motorcycle_right.png',
          'brick.png','grass.png','gravel.png','coins.png','moon.png','clock_motion.png','rocket.jpg']:
    open('photos/' + n, 'wb').write(z.read('skimage/data/' + n))")
fi
FR="$TMP/frames"; mkdir -p "$FR"
for i in 0 10 20 30 40 50; do n=$(printf %06d $i); ln -s "$DATA/kitti/sequences/06/image_0/$n.png" "$FR/k06_$n.png"; done
for i in $(seq 0 20 159); do n=$(printf %06d $i); ln -s "$DATA/kitti/sequences/07/image_0/$n.png" "$FR/k07_$n.png"; done
ls "$DATA/euroc/V1_01_easy_first95/mav0/cam0/data" | awk 'NR%10==1' | while read -r f; do ln -s "$DATA/euroc/V1_01_easy_first95/mav0/cam0/data/$f" "$FR/euroc_$f"; done
ls "$DATA/sevenscenes/kitchen_first300/rgb" | awk 'NR%30==1' | while read -r f; do ln -s "$DATA/sevenscenes/kitchen_first300/rgb/$f" "$FR/kitchen_$f"; done
REDUCE=""; grep -q avx512_vnni /proc/cpuinfo || REDUCE="--reduce-range"
$PY tools/quantize_superpoint.py --weights "$W" --out "$TMP/cand_int8.onnx" --data "$DATA" $REDUCE >&2
BASE=shipped; BASE_EXTRACT=(); BASE_LABEL="the shipped model"; BASE_COLUMN=shipped
if [[ -n "$B" ]]; then
    BASE_LABEL="$(basename "$B") (sha256 $(sha256sum "$B" | cut -c1-12))"; BASE_COLUMN=baseline
    $PY tools/quantize_superpoint.py --weights "$B" --out "$TMP/base_int8.onnx" --data "$DATA" $REDUCE >&2
    BASE="baseline=$TMP/base_int8.onnx"; BASE_EXTRACT=(--model "$TMP/base_int8.onnx")
fi
echo "Commit $(git rev-parse --short HEAD), CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs) ($(grep -q avx512_vnni /proc/cpuinfo && echo 'AVX-512 VNNI' || echo 'AVX2, no VNNI')), candidate $(basename "$W") (sha256 $(sha256sum "$W" | cut -c1-12)), baseline $BASE_LABEL, int8 ${REDUCE:+(7-bit weights, as spslam picks on this CPU)}"
$PY tools/bench_homography.py --images "$HELD/photos" --pairs 3 --model "$BASE" --model candidate="$TMP/cand_int8.onnx" \
    --label "held-out photographs (the 13 of scikit-image 0.25.2's data)"
$PY tools/bench_homography.py --images "$FR" --pairs 2 --max-side 1280 --model "$BASE" --model candidate="$TMP/cand_int8.onnx" \
    --label "the shared excerpts' frames (KITTI 06 x6, KITTI 07 x8, EuRoC V1_01 x10, 7-Scenes kitchen x10)"
$PY tools/stereo_same_row.py --left "$DATA/kitti/sequences/06/image_0" --right "$DATA/kitti/sequences/06/image_1" \
    --every 5 --model "$BASE" --model candidate="$TMP/cand_int8.onnx" --label "KITTI 06 excerpt"
cargo run --release --quiet --example rectify_euroc -- "$DATA/euroc/V1_01_easy_first95" "$TMP/euroc_rect" 5 >&2
$PY tools/stereo_same_row.py --left "$TMP/euroc_rect/left" --right "$TMP/euroc_rect/right" \
    --every 1 --model "$BASE" --model candidate="$TMP/cand_int8.onnx" \
    --label "EuRoC V1_01 excerpt, every 5th pair, rectified as spslam run does (examples/rectify_euroc)"
echo
echo "Periodic artefact: flat dark noise (640x480, mean 8-20, sd 1.5-3), 1000 keypoints, filter off: share on the most common sub-cell phase (uniform: 1.6 %)"
echo
echo "| image | $BASE_COLUMN | candidate |"
echo "|---|---|---|"
$PY -c "
import numpy as np; from PIL import Image
rng = np.random.default_rng(0)
for i, (m, s) in enumerate([(12, 2), (20, 3), (8, 1.5)]):
    Image.fromarray(np.clip(rng.normal(m, s, (480, 640)), 0, 255).astype(np.uint8)).save('$TMP/dark%d.png' % i)"
for i in 0 1 2; do
    a=$(./target/release/spslam extract "$TMP/dark$i.png" --no-periodic-filter "${BASE_EXTRACT[@]}" | grep -o 'holds [0-9.]*%' | cut -d' ' -f2)
    b=$(./target/release/spslam extract "$TMP/dark$i.png" --no-periodic-filter --model "$TMP/cand_int8.onnx" | grep -o 'holds [0-9.]*%' | cut -d' ' -f2)
    echo "| dark$i | $a | $b |"
done
