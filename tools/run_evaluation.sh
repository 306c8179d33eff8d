#!/bin/bash
# Runs the runs behind EVALUATION.md: ORB, SuperPoint and SuperPoint + ANMS
# on the KITTI 06 and EuRoC V1_01 excerpts, on 500-frame synthetic
# straight and loop sequences and on the 300-frame synthetic highway.
# Local mapping runs inline so that the per-frame times add up; then
# tools/evaluation_table.py prints the table.
#
#   tools/run_evaluation.sh [OUT [SEQUENCE...]]   (default OUT: out/evaluation;
#                                                  SEQUENCE: kitti euroc straight loop highway)
#
# Needs ../shared/data (or SPSLAM_DATA) and a release build. SuperPoint on
# 8 levels takes 3–4 s per stereo frame on a 2-core machine; the synthetic
# sequences use one level (--levels 1) to keep the whole run near an hour.
set -euo pipefail
OUT=${1:-out/evaluation}
shift || true
ONLY=" ${*:-kitti euroc straight loop highway} "
DATA=${SPSLAM_DATA:-../shared/data}
BIN=./target/release/spslam
mkdir -p "$OUT"
[ -d "$OUT/synth_straight" ] || $BIN synth --out "$OUT/synth_straight" --scene straight --frames 500 --no-depth
[ -d "$OUT/synth_loop" ] || $BIN synth --out "$OUT/synth_loop" --scene loop --frames 500 --no-depth
[ -d "$OUT/synth_highway" ] || $BIN synth --out "$OUT/synth_highway" --scene highway --frames 300 --no-depth
run() { local name=$1; shift; echo "== $name"; $BIN run --inline-mapping --out "$OUT/$name" "$@" > "$OUT/$name.log"; }
for ds in "kitti kitti:$DATA/kitti" "euroc euroc:$DATA/euroc/V1_01_easy_first95" \
          "straight synth:$OUT/synth_straight" "loop synth:$OUT/synth_loop" \
          "highway synth:$OUT/synth_highway"; do
  set -- $ds
  case "$ONLY" in *" $1 "*) ;; *) continue;; esac
  levels=""
  case $1 in straight|loop|highway) levels="--levels 1";; esac
  run "${1}_orb" --dataset "$2" --extractor orb
  run "${1}_sp_none" --dataset "$2" --extractor superpoint --anms none $levels
  run "${1}_sp_anms" --dataset "$2" --extractor superpoint --anms kdtree $levels
done
python3 tools/evaluation_table.py "$OUT"
