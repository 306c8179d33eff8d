#!/usr/bin/env bash
# The Python package (python/): `build` writes the abi3 wheel into
# target/wheels/ (maturin, with the models of models/ inside); `test`
# installs that wheel into a fresh venv (.deps/venv-wheel-test, with its
# PyPI dependencies: numpy, onnxruntime==1.31.1) and runs python/tests.
set -euo pipefail
cd "$(dirname "$0")/.."

MATURIN_VERSION=1.16.0
VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' python/Cargo.toml | head -1)
WHEEL=target/wheels/spslam-${VERSION}-cp39-abi3-linux_x86_64.whl

build() {
    if ! .deps/venv/bin/maturin --version 2>/dev/null | grep -q " ${MATURIN_VERSION}$"; then
        .deps/venv/bin/python -m pip install --disable-pip-version-check -q "maturin==${MATURIN_VERSION}"
    fi
    local missing=0
    for model in superpoint.onnx superpoint_int8.onnx superpoint_lite.onnx superpoint_lite_int8.onnx; do
        [[ -f models/$model ]] || { echo "error: models/$model is missing; run \`make setup\`" >&2; missing=1; }
    done
    (( missing == 0 )) || exit 1
    rm -rf python/spslam/models
    mkdir -p python/spslam/models
    cp models/*.onnx models/*.spvlad python/spslam/models/
    # `--compatibility linux`: the module links Debian's OpenCV 4.6
    # (libopencv-dev), so the wheel is for machines that have it, not
    # manylinux. `--strip`: the release profile's line tables stay out.
    .deps/venv/bin/maturin build --release --strip --compatibility linux \
        --manifest-path python/Cargo.toml --out target/wheels
    echo "wheel: $WHEEL ($(du -h "$WHEEL" | cut -f1))"
}

test_wheel() {
    [[ -f $WHEEL ]] || { echo "error: $WHEEL is missing; run \`make python\`" >&2; exit 1; }
    local venv=.deps/venv-wheel-test
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --disable-pip-version-check -q "$WHEEL" pytest pillow
    # From the tests' folder, so that python/spslam (the sources, without
    # the compiled module) cannot shadow the installed package.
    (cd python/tests && SPSLAM_BIN="$PWD/../../target/release/spslam" \
        "../../$venv/bin/python" -m pytest -q -p no:cacheprovider .)
}

case "${1:-}" in
    build) build ;;
    test) test_wheel ;;
    *) echo "usage: $0 build|test" >&2; exit 2 ;;
esac
