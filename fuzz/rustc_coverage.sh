#!/usr/bin/env bash
# RUSTC_WORKSPACE_WRAPPER for fuzz/run.sh's stable builds: rustc, with
# libFuzzer's coverage flags ($SPSLAM_FUZZ_RUSTFLAGS) added for spslam's
# library and the fuzz target `c_abi` only. Cargo calls a workspace wrapper
# for workspace members alone, so the dependencies are the ones `make
# python` already compiled into target/release (same profile, lock file and
# features) rather than a second, instrumented copy; build scripts and
# cargo's probes run plain rustc.
set -euo pipefail
rustc=$1
shift
crate=
previous=
for arg in "$@"; do
    [[ $previous == --crate-name ]] && crate=$arg
    previous=$arg
done
case "$crate" in
    spslam | c_abi)
        # shellcheck disable=SC2086 # the flags are a space-separated list
        exec "$rustc" "$@" ${SPSLAM_FUZZ_RUSTFLAGS:?} ;;
    *) exec "$rustc" "$@" ;;
esac
