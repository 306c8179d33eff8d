#!/usr/bin/env bash
# make test-viewer: records `spslam run` on the KITTI 06 excerpt with
# --rerun and checks the recording with rerun's own reader
# (tools/test_rerun_recording.py). Missing data fails under CI=true and
# skips elsewhere, like the other tests.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: $0 OUT_DIR}
data=${SPSLAM_DATA:-../shared/data}
seq=$data/kitti/sequences/06
if [[ ! -d $seq/image_0 ]]; then
    if [[ ${CI:-} == true ]]; then
        echo "error: the KITTI 06 excerpt is missing ($seq) and CI=true" >&2
        exit 1
    fi
    echo "SKIPPED test-viewer: the KITTI 06 excerpt is missing ($seq)"
    exit 0
fi
rm -rf "$out"
mkdir -p "$out"
if ! ./target/release/spslam run --dataset "kitti:$seq" --settings settings/KITTI04-12.yaml \
    --out "$out" --rerun "$out/run.rrd" 2>"$out/stderr.txt" >"$out/stdout.txt"; then
    cat "$out/stderr.txt" >&2
    exit 1
fi
grep "^viewer:" "$out/stderr.txt"
.deps/venv-viewer/bin/python tools/test_rerun_recording.py "$out"
