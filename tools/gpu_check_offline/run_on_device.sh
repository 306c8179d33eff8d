#!/usr/bin/env bash
# The device side of tools/gpu_check_offline: unpacks what pack.sh made
# (copied to /root/chunks by the earlier calls) and runs gpu_check with
# ONNX Runtime's PyPI GPU build and the CUDA 13 / cuDNN 9 libraries of the
# machine's PyTorch. Output also goes to $OUT/gpu_check.log.
set -u
C=/root/chunks; R=/root/gpurun; KEEP_SM=90
LOG="${OUT:-/tmp}/gpu_check.log"
mkdir -p "$R" && cd "$R" || exit 1
unxz() { python3 -c "import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2],'wb'), 1<<24)" "$1" "$2"; }
unxz $C/zeroed.xz libonnxruntime_providers_cuda.so || exit 1
if ls $C/rest.xz.part* >/dev/null 2>&1; then
    cat $C/rest.xz.part* > rest.xz && unxz rest.xz rest.bin \
        && python3 $C/fatbin_split.py restore libonnxruntime_providers_cuda.so $KEEP_SM rest.bin full.so \
        && mv full.so libonnxruntime_providers_cuda.so && echo "all architectures restored"
fi
unxz $C/core.xz libonnxruntime.so.1.31.1 && unxz $C/bundle.tar.xz bundle.tar && tar -xf bundle.tar || exit 1
cp $C/shared.so libonnxruntime_providers_shared.so
NV=$(python3 -c "import nvidia,glob; print(':'.join(sorted(d for p in nvidia.__path__ for d in glob.glob(p+'/*/lib'))))" 2>/dev/null)
[ -n "$NV" ] || NV=$(find /opt /usr -type d -path '*site-packages/nvidia/*/lib' 2>/dev/null | sort | paste -sd: -)
export LD_LIBRARY_PATH=$R/cv:$NV SPSLAM_MODELS_DIR=$R/models ORT_DYLIB_PATH=$R/libonnxruntime.so.1.31.1
nvidia-smi -L; nvidia-smi --query-gpu=driver_version --format=csv,noheader
lscpu | grep -E 'Model name|^CPU\(s\)'
# Each run is "ENVIRONMENT|ARGUMENTS": variable assignments for gpu_check
# (SPSLAM_CUDA_CONV_SEARCH, SPSLAM_CUDA_SESSION_PER_SHAPE), then its
# precision, levels and frames. The GPU's memory in use is polled every
# 0.2 s during each run; its peak above the idle reading is printed.
RUNS=${GPU_CHECK_RUNS:-"SPSLAM_CUDA_CONV_SEARCH=heuristic|fp32 1 100;SPSLAM_CUDA_CONV_SEARCH=heuristic|fp32 8 100;SPSLAM_CUDA_CONV_SEARCH=exhaustive|fp32 8 100"}
gpu_memory() { local m; m=$(nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits 2>/dev/null | head -n1); echo "${m:-0}"; }
IFS=';' read -ra runs <<< "$RUNS"
for run in "${runs[@]}"; do
    environment=${run%%|*}; arguments=${run#*|}
    echo "=== $environment gpu_check $arguments" | tee -a "$LOG"
    idle=$(gpu_memory); peak=$idle
    # shellcheck disable=SC2086
    env $environment timeout 100 ./gpu_check $arguments kitti06_000000.pgm > run.out 2>&1 &
    pid=$!
    while kill -0 $pid 2>/dev/null; do
        used=$(gpu_memory); (( used > peak )) && peak=$used; sleep 0.2
    done
    wait $pid
    cat run.out | tee -a "$LOG"
    echo "  GPU memory: peak $((peak - idle)) MiB above idle ($idle MiB)" | tee -a "$LOG"
done
