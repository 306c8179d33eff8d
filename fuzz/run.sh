#!/usr/bin/env bash
# Builds and runs the C ABI fuzzer (fuzz_targets/c_abi.rs) with libFuzzer.
#
#   fuzz/run.sh short            # make test: replay the corpus, then fuzz 60 s (stable)
#   fuzz/run.sh long [ARGS...]   # the long run: AddressSanitizer + LeakSanitizer
#                                # (nightly toolchain), libFuzzer ARGS appended,
#                                # e.g. -runs=10000000 -jobs=2 -workers=2
#   fuzz/run.sh campaign [ARGS...] # the stable build, libFuzzer ARGS appended
#                                # (no sanitizer: the fastest, for counts),
#                                # e.g. -runs=5000000 -jobs=2 -workers=2
#
# Stable Rust cannot build with AddressSanitizer (-Zsanitizer), so the short
# run checks for crashes, panics and failed assertions only; the long run, on
# a machine with a nightly toolchain, adds memory errors and leaks.
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-short}
shift || true

export SPSLAM_FUZZ_TINY_MODEL="$PWD/target/tiny_superpoint.onnx"
mkdir -p target corpus/c_abi artifacts target/seeds
# seeds.tar.gz: a minimised corpus (-merge=1) of earlier runs, the start.
tar -xzf seeds.tar.gz -C target/seeds
[[ -f "$SPSLAM_FUZZ_TINY_MODEL" ]] || ../.deps/venv/bin/python make_tiny_model.py "$SPSLAM_FUZZ_TINY_MODEL"

flags="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4"
flags+=" -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table"
# No compare tracing (-sanitizer-coverage-trace-compares): it put 64 % of
# the time into libFuzzer's __sanitizer_cov_trace_cmp8 hooks inside the
# numeric kernels (NMS, orientation, descriptor sampling), and without it the
# same 120 s ran 2.6x the inputs and reached more coverage (BENCHMARKS.md,
# 'C ABI fuzzing'). The harness builds its values with `arbitrary`, so there
# are no magic constants for compare tracing to solve.
flags+=" -Cdebug-assertions -Coverflow-checks"
case "$mode" in
  short|campaign)
    # Only spslam's library and the target are instrumented (rustc_coverage.sh,
    # a workspace wrapper); the dependencies are shared with the other release
    # builds in ../target (`make test` builds the Python wheel's first), where
    # instrumenting every crate meant compiling them all again (4 min of the
    # 5 min build here). The `fuzzing` feature keeps this spslam apart from
    # the plain one.
    (cd .. && SPSLAM_FUZZ_RUSTFLAGS="$flags" RUSTC_WORKSPACE_WRAPPER="$PWD/fuzz/rustc_coverage.sh" \
      cargo build --release -p spslam-fuzz --bin c_abi)
    bin=../target/release/c_abi ;;
  long)
    # AddressSanitizer wants every crate instrumented: its own target folder,
    # and --target keeps the flags off build scripts and proc macros (as
    # cargo fuzz does).
    target=x86_64-unknown-linux-gnu
    flags+=" -Zsanitizer=address -Cforce-frame-pointers"
    RUSTFLAGS="$flags" cargo +nightly build --release --target "$target" \
      --target-dir target/asan -p spslam-fuzz --bin c_abi
    bin="target/asan/$target/release/c_abi" ;;
  *) echo "usage: fuzz/run.sh short|long|campaign [libFuzzer args]" >&2; exit 2 ;;
esac

# Leaks in ONNX Runtime's own process-lifetime singletons are not ours.
printf 'leak:libonnxruntime\n' > target/lsan.supp
export LSAN_OPTIONS="suppressions=$PWD/target/lsan.supp:print_suppressions=0"
export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1"

# The crashers found so far (fixed) replay first: regression tests.
regressions=(regressions/crash-* regressions/leak-* regressions/oom-* regressions/timeout-*)
existing=()
for f in "${regressions[@]}"; do [[ -f $f ]] && existing+=("$f"); done
if (( ${#existing[@]} )); then
  "$bin" -runs=1 "${existing[@]}"
fi
case "$mode" in
  short) "$bin" -max_len=1024 -max_total_time=60 -print_final_stats=1 -artifact_prefix=artifacts/ corpus/c_abi target/seeds ;;
  long|campaign) "$bin" -max_len=1024 -print_final_stats=1 -artifact_prefix=artifacts/ "$@" corpus/c_abi target/seeds ;;
esac
