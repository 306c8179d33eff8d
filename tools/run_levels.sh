#!/bin/bash
# Runs behind EVALUATION.md's pyramid-level table: `spslam run` with
# SuperPoint + kd-tree ANMS on 1, 2, 4 and 8 pyramid levels, fp32 and int8,
# on the KITTI 06 and EuRoC V1_01 excerpts and a 100-frame synthetic
# highway (640x480). Local mapping runs inline (deterministic); then
# tools/levels_table.py prints the table.
#
#   tools/run_levels.sh [OUT [SEQUENCE...]]   (default OUT: out/levels;
#                                              SEQUENCE: kitti euroc highway)
#
# Needs ../shared/data (or SPSLAM_DATA), `make setup` (both models) and a
# release build. About 45 minutes on a 2-core machine.
set -euo pipefail
OUT=${1:-out/levels}
shift || true
ONLY=" ${*:-kitti euroc highway} "
DATA=${SPSLAM_DATA:-../shared/data}
BIN=${SPSLAM_BIN:-./target/release/spslam}
mkdir -p "$OUT"
[ -d "$OUT/synth_highway" ] || $BIN synth --out "$OUT/synth_highway" --scene highway --frames 100 --no-depth
for ds in "kitti kitti:$DATA/kitti" "euroc euroc:$DATA/euroc/V1_01_easy_first95" \
          "highway synth:$OUT/synth_highway"; do
  set -- $ds
  case "$ONLY" in *" $1 "*) ;; *) continue;; esac
  for precision in int8 fp32; do
    for levels in 1 2 4 8; do
      name="${1}_${precision}_l${levels}"
      [ -f "$OUT/$name/report.json" ] && continue
      echo "== $name"
      $BIN run --inline-mapping --device cpu --precision "$precision" --levels "$levels" \
        --dataset "$2" --out "$OUT/$name" > "$OUT/$name.log" 2>&1 || echo "   $name: exit $?"
    done
  done
done
python3 tools/levels_table.py "$OUT"
