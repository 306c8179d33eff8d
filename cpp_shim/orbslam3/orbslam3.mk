# cpp_shim/orbslam3/orbslam3.mk: the ORB-SLAM3 preload (libspslam_orbslam3.so
# + libspslam_orbslam3_impl.so) and the check that runs the real ORB-SLAM3 v1.0
# from the PyPI wheel orbslam3-python==2.0.0 with it.
#
#   make orbslam3-build   the two libraries, in target/orbslam3/
#   make orbslam3-check   ORB-SLAM3 stereo on KITTI 06 three ways (ORB, float,
#                         binary), three runs each; out/orbslam3/{orb,float,binary}/
#                         SEQ=DIR GT=FILE: any KITTI-layout sequence
#
# Included from the top Makefile after cpp_shim/cpp.mk (CPP_* variables, rust-release, build).

ORBSLAM3_VENV ?= .deps/venv-orbslam3
ORBSLAM3_BUILD_DIR ?= target/orbslam3
ORBSLAM3_DIR := $(CPP_SHIM_DIR)/orbslam3
ORBSLAM3_PRELOAD := $(ORBSLAM3_BUILD_DIR)/libspslam_orbslam3.so
ORBSLAM3_IMPL := $(ORBSLAM3_BUILD_DIR)/libspslam_orbslam3_impl.so
ORBSLAM3_STAMP := $(ORBSLAM3_VENV)/.spslam-orbslam3-installed
# The wheel's own OpenCV 4.8 (the implementation links it, never Debian's).
# (`shell`, not `wildcard`: make caches folder listings, and the venv may be
# created by this very make run.)
ORBSLAM3_LIBS = $(shell ls -d $(abspath $(ORBSLAM3_VENV))/lib/python3*/site-packages/orbslam3_python.libs 2>/dev/null | head -n1)
ORBSLAM3_CV_LIBS = $(foreach m,core imgproc,-l:$(shell cd $(ORBSLAM3_LIBS) 2>/dev/null && ls libopencv_$(m)-*.so.4.8.0 | head -n1))
ORBSLAM3_CXXFLAGS := -std=c++17 -O2 -g -Wall -Wextra -fPIC
SEQ ?=
GT ?=
ORBSLAM3_RUNS ?= 3

.PHONY: orbslam3-setup orbslam3-build orbslam3-check

orbslam3-setup: $(ORBSLAM3_STAMP)

$(ORBSLAM3_STAMP): tools/orbslam3/setup.sh
	@bash tools/orbslam3/setup.sh $(ORBSLAM3_VENV)

orbslam3-build: $(ORBSLAM3_PRELOAD) $(ORBSLAM3_IMPL)

# No OpenCV library and no spslam: only inline cv::Mat accessors (-z defs proves it).
$(ORBSLAM3_PRELOAD): $(ORBSLAM3_DIR)/preload.cc $(ORBSLAM3_DIR)/float_distance.h
	@mkdir -p $(ORBSLAM3_BUILD_DIR)
	$(CXX) $(ORBSLAM3_CXXFLAGS) -O3 $(CPP_OPENCV_CFLAGS) -shared -o $@ $< -Wl,-z,defs -ldl

# The shim and spslam's static library with hidden visibility, linked against
# the wheel's OpenCV only; exports the five spslam_orbslam3_* entry points.
$(ORBSLAM3_BUILD_DIR)/%.pic.o: $(CPP_SHIM_DIR)/%.cc $(CPP_HEADERS) $(ORBSLAM3_STAMP) | $(CPP_SPSLAM_LIB)
	@mkdir -p $(ORBSLAM3_BUILD_DIR)
	$(CXX) $(ORBSLAM3_CXXFLAGS) -fvisibility=hidden -fvisibility-inlines-hidden $(CPP_INCLUDES) -c $< -o $@

$(ORBSLAM3_BUILD_DIR)/impl.pic.o: $(ORBSLAM3_DIR)/impl.cc $(CPP_HEADERS) $(ORBSLAM3_STAMP) | $(CPP_SPSLAM_LIB)
	@mkdir -p $(ORBSLAM3_BUILD_DIR)
	$(CXX) $(ORBSLAM3_CXXFLAGS) -fvisibility=hidden -fvisibility-inlines-hidden $(CPP_INCLUDES) -c $< -o $@

$(ORBSLAM3_IMPL): $(ORBSLAM3_BUILD_DIR)/impl.pic.o $(ORBSLAM3_BUILD_DIR)/ORBextractor.pic.o $(CPP_SPSLAM_LIB) $(ORBSLAM3_STAMP)
	$(CXX) -shared -o $@ $(filter %.o,$^) $(CPP_SPSLAM_LIB) -L$(ORBSLAM3_LIBS) $(ORBSLAM3_CV_LIBS) \
		-Wl,-rpath,$(ORBSLAM3_LIBS) -Wl,--gc-sections -Wl,--exclude-libs,ALL -Wl,-z,defs -lpthread -ldl -lm

orbslam3-check: orbslam3-build build
	$(ORBSLAM3_VENV)/bin/python tools/orbslam3/check.py --runs $(ORBSLAM3_RUNS) --out $(OUT)/orbslam3 \
		--preload $(ORBSLAM3_PRELOAD) $(if $(SEQ),--seq $(SEQ)) $(if $(GT),--gt $(GT)) $(if $(MODEL),--model $(MODEL))
