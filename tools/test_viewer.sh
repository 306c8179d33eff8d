#!/usr/bin/env bash
# make test-viewer: records `spslam run` on the KITTI 06 excerpt with
# --rerun and checks the recording with rerun's own reader
# (tools/test_rerun_recording.py). Missing data fails under CI=true and
# skips elsewhere, like the other tests. Then a run whose viewer went away
# must still finish and write its outputs.
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

# A viewer that goes away never holds the run nor its outputs: `--viewer`
# with an "executable" that exits at once (the viewer closed, or it could
# not start) must finish, write the trajectory, and say what happened.
gone=$out/viewer_gone
mkdir -p "$gone"
if ! SPSLAM_RERUN=/bin/true timeout 600 ./target/release/spslam run --dataset "kitti:$seq" \
    --settings settings/KITTI04-12.yaml --frames 12 --out "$gone" --viewer \
    2>"$gone/stderr.txt" >"$gone/stdout.txt"; then
    cat "$gone/stderr.txt" >&2
    echo "error: spslam run --viewer failed or hung when the viewer went away" >&2
    exit 1
fi
if [[ $(wc -l < "$gone/trajectory_kitti.txt") -ne 12 ]]; then
    echo "error: with the viewer gone, the trajectory does not hold the 12 frames" >&2
    exit 1
fi
grep "warning: the viewer failed: the viewer took no data" "$gone/stderr.txt" \
    || { echo "error: no warning that the viewer took no data" >&2; exit 1; }
echo "viewer gone: the run finished with its 12-frame trajectory and a warning"
