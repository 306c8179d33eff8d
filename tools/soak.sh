#!/usr/bin/env bash
# The soak run (`make soak`, EVALUATION.md 'Soak'): FRAMES frames of the
# synthetic city-block loop (232 frames a lap, so 10,000 frames are 43
# laps; 320x240 with a 200 px focal length: the 640x480 scene's field of
# view), stereo SLAM with the defaults (SuperPoint int8, one level, loop
# closing on), the resident memory and the atlas' size every 100 frames,
# then the figures (tools/soak_table.py).
#
#   tools/soak.sh DIR [FRAMES]     # DIR/sequence is rendered once and reused
#
# SPSLAM_BIN names the spslam binary (default ./target/release/spslam): a
# copy keeps a half-hour run safe from a rebuild meanwhile.
set -euo pipefail
dir=${1:?usage: tools/soak.sh DIR [FRAMES]}
frames=${2:-10000}
seq=$dir/sequence
spslam=${SPSLAM_BIN:-./target/release/spslam}
if [[ ! -f $seq/poses/00.txt ]] || [[ $(wc -l < "$seq/poses/00.txt") -ne $frames ]]; then
  $spslam synth --out "$seq" --scene loop --frames "$frames" --size 320x240 --focal 200 \
    --no-depth --overwrite
fi
mkdir -p "$dir/run"
git rev-parse --short HEAD > "$dir/run/commit.txt" 2>/dev/null || true
$spslam run --dataset "synth:$seq" --out "$dir/run" \
  --memory-log "$dir/run/memory.csv" --memory-every 100
python3 tools/soak_table.py "$dir/run"
