# cpp_shim/cpp.mk: the ORB-SLAM3 ORBextractor shim, its test and its example,
# built with plain g++ against target/release/libspslam.a.
#
# Included from the top Makefile, which defines `rust-release` (cargo build
# --release) and the set-up (model + ONNX Runtime) that `cpp-test` needs.
#
#   make cpp-build     compile the shim, tests/test_orbextractor and examples/stereo_kitti
#   make cpp-test      run the test on KITTI frames, then again on a 64x48 crop
#                      under valgrind with a tiny model of SuperPoint's interface
#                      (fuzz/make_tiny_model.py: the shim, the C ABI and their use
#                      of ONNX Runtime are what is checked, not the network's
#                      kernels; about 40 s instead of 9 min with the real int8
#                      model). Errors and definite leaks fail the target;
#                      CPP_VALGRIND=0 skips that run.
#   make cpp-example   run the stereo KITTI example
#
# Variables: CARGO, SPSLAM_DATA (KITTI data root), CXX, CPP_BUILD_DIR, VALGRIND, CPP_VALGRIND.

CARGO ?= cargo
SPSLAM_DATA ?= ../shared/data

CPP_SHIM_DIR := cpp_shim
CPP_BUILD_DIR ?= target/cpp-shim
CPP_CXXFLAGS ?= -std=c++17 -O2 -g -Wall -Wextra
CPP_OPENCV_CFLAGS ?= $(shell pkg-config --cflags opencv4 2>/dev/null || echo -I/usr/include/opencv4)
CPP_INCLUDES := -Iinclude -I$(CPP_SHIM_DIR) $(CPP_OPENCV_CFLAGS)
CPP_SPSLAM_LIB := target/release/libspslam.a
CPP_LDLIBS := $(CPP_SPSLAM_LIB) -lopencv_calib3d -lopencv_features2d -lopencv_flann -lopencv_imgcodecs -lopencv_imgproc -lopencv_core -lpthread -ldl -lm

VALGRIND ?= valgrind
CPP_VALGRIND ?= 1
CPP_VALGRIND_FLAGS ?= --error-exitcode=1 --leak-check=full --errors-for-leak-kinds=definite \
	--suppressions=$(CPP_SHIM_DIR)/valgrind.supp --num-callers=40

CPP_TEST_BIN := $(CPP_BUILD_DIR)/test_orbextractor
CPP_TINY_MODEL := $(CPP_BUILD_DIR)/tiny_superpoint.onnx
CPP_DISTANCE_TEST_BIN := $(CPP_BUILD_DIR)/test_float_distance
CPP_EXAMPLE_BIN := $(CPP_BUILD_DIR)/stereo_kitti
CPP_HEADERS := include/spslam.h $(CPP_SHIM_DIR)/ORBextractor.h

.PHONY: cpp-build cpp-test cpp-example

cpp-build: $(CPP_TEST_BIN) $(CPP_EXAMPLE_BIN) $(CPP_DISTANCE_TEST_BIN)

# The ORB-SLAM3 preload's descriptor distances (header only, no library).
$(CPP_DISTANCE_TEST_BIN): $(CPP_SHIM_DIR)/tests/test_float_distance.cc $(CPP_SHIM_DIR)/orbslam3/float_distance.h
	@mkdir -p $(CPP_BUILD_DIR)
	$(CXX) $(CPP_CXXFLAGS) -I$(CPP_SHIM_DIR) $< -o $@

# The Rust library comes from `rust-release` (defined by the top Makefile);
# the empty recipe makes make re-read its time stamp after cargo ran, so the
# binaries are relinked against a fresh library (and the objects compile
# only after it exists, also under -j).
$(CPP_SPSLAM_LIB): rust-release ;

$(CPP_BUILD_DIR)/ORBextractor.o: $(CPP_SHIM_DIR)/ORBextractor.cc $(CPP_HEADERS) | $(CPP_SPSLAM_LIB)
	@mkdir -p $(CPP_BUILD_DIR)
	$(CXX) $(CPP_CXXFLAGS) $(CPP_INCLUDES) -c $< -o $@

$(CPP_BUILD_DIR)/test_orbextractor.o: $(CPP_SHIM_DIR)/tests/test_orbextractor.cc $(CPP_HEADERS) | $(CPP_SPSLAM_LIB)
	@mkdir -p $(CPP_BUILD_DIR)
	$(CXX) $(CPP_CXXFLAGS) $(CPP_INCLUDES) -c $< -o $@

$(CPP_BUILD_DIR)/stereo_kitti.o: $(CPP_SHIM_DIR)/examples/stereo_kitti.cc $(CPP_HEADERS) | $(CPP_SPSLAM_LIB)
	@mkdir -p $(CPP_BUILD_DIR)
	$(CXX) $(CPP_CXXFLAGS) $(CPP_INCLUDES) -c $< -o $@

$(CPP_TEST_BIN): $(CPP_BUILD_DIR)/test_orbextractor.o $(CPP_BUILD_DIR)/ORBextractor.o $(CPP_SPSLAM_LIB)
	$(CXX) -o $@ $(filter %.o,$^) $(CPP_LDLIBS)

$(CPP_EXAMPLE_BIN): $(CPP_BUILD_DIR)/stereo_kitti.o $(CPP_BUILD_DIR)/ORBextractor.o $(CPP_SPSLAM_LIB)
	$(CXX) -o $@ $(filter %.o,$^) $(CPP_LDLIBS)

# The tiny model (seeded weights: the same file every time) for the valgrind run.
$(CPP_TINY_MODEL): fuzz/make_tiny_model.py | setup
	@mkdir -p $(CPP_BUILD_DIR)
	.deps/venv/bin/python $< $@

cpp-test: cpp-build $(if $(filter 0,$(CPP_VALGRIND)),,$(CPP_TINY_MODEL))
	$(CPP_DISTANCE_TEST_BIN)
	$(CPP_TEST_BIN) $(SPSLAM_DATA)
ifneq ($(CPP_VALGRIND),0)
	SPSLAM_MODEL=$(abspath $(CPP_TINY_MODEL)) SPSLAM_MODEL_INT8=$(abspath $(CPP_TINY_MODEL)) SPSLAM_THREADS=1 \
		$(VALGRIND) $(CPP_VALGRIND_FLAGS) $(CPP_TEST_BIN) --small $(SPSLAM_DATA)
else
	@echo "cpp-test: valgrind run skipped (CPP_VALGRIND=0)"
endif

cpp-example: cpp-build
	$(CPP_EXAMPLE_BIN) $(SPSLAM_DATA)
