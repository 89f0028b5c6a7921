#!/usr/bin/env bash
# One session on a lent GPU machine (16 cores, one H100), run from the repository's root:
# the Rust GPU tests on the real GPU, then photo-like samples synthesised on the CPUs while
# the nets train on the GPU from them (resident mode, following the growing folder).
#
# Made ready on the development machine (docs/nets.md, "Training on a GPU"):
#   .dev/it.xz             the release test binary (cargo test --release --no-run --test it), stripped
#   .dev/matedit.so.xz     the Python package's extension (maturin build --release), stripped
#   .dev/data.tar.xz       photo/{meshes/train, envmaps}: the training spec's inputs
#   .gl/*.deb              the Vulkan loader (the device's README)
# (.dev/it.xz is optional: without it the GPU tests are skipped.)
# Writes to $OUT: gpu_tests.log, runs.tar.xz (every run's log, run.json, losses.png) and
# each run's weights.
#
#   [SHARDS=8 PAPER_SHARDS=4] bash python/examples/nets/photo/device.sh SECONDS RUN...     RUN: a config of this folder
set -u
seconds=$1
shift
out=${OUT:-/tmp/out}
mkdir -p "$out" /tmp/dev /tmp/site/matedit /tmp/runs
t0=$(date +%s)
stamp() { echo "[$(($(date +%s) - t0)) s] $*"; }

if ! ldconfig -p | grep -q libvulkan.so.1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f $icd ] && export VK_DRIVER_FILES=$icd __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f .dev/it.xz ] && xz -dc .dev/it.xz >/tmp/dev/it && chmod +x /tmp/dev/it
cp -r python/matedit/. /tmp/site/matedit/
xz -dc .dev/matedit.so.xz >/tmp/site/matedit/_matedit.abi3.so
tar -C /tmp/dev -xJf .dev/data.tar.xz
cp python/examples/nets/photo/{train,paper128}.json /tmp/dev/photo/
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1 PYTORCH_CUDA_ALLOC_CONF=expandable_segments:True
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
stamp "unpacked"

# the synthesis, one thread a process: SHARDS processes writing the photo-like folder and
# PAPER_SHARDS the paper's kind (paper128.json), for the runs whose data lists both
synth() {  # SPEC FOLDER SHARDS
    for i in $(seq 0 $(($3 - 1))); do
        python3 -c "import matedit; matedit.synth('/tmp/dev/photo/$1', '$2', shard=($i, $3), threads=1)" \
            >/tmp/runs/synth-$(basename $2)-$i.log 2>&1 &
    done
}
synth train.json /tmp/ds ${SHARDS:-12}
[ "${PAPER_SHARDS:-0}" -gt 0 ] && synth paper128.json /tmp/ds_paper $PAPER_SHARDS

# the GPU tests beside the training: those whose names say gpu, and the comparisons of
# every backend with the reference
if [ -x /tmp/dev/it ]; then
    (MATEDIT_REQUIRE_GPU=1 timeout ${TEST_SECONDS:-240} /tmp/dev/it gpu backends:: every_backend_gives_the_references_corrections sweeps_hold_on_every_path \
        --test-threads 4 >"$out/gpu_tests.log" 2>&1
     stamp "GPU tests: exit $? ($(grep -c '\.\.\. ok' "$out/gpu_tests.log") ok, $(grep -c 'FAILED\|panicked' "$out/gpu_tests.log") failed)") &
fi
folders=/tmp/ds
[ "${PAPER_SHARDS:-0}" -gt 0 ] && folders="/tmp/ds /tmp/ds_paper"
for f in $folders; do until ls $f/chunk-*.json >/dev/null 2>&1; do sleep 1; done; done
stamp "$(cat /tmp/ds*/chunk-*.json | grep -c '"file"') chunks so far"
mkdir -p python/examples/nets/photo/data
ln -sfn /tmp/ds python/examples/nets/photo/data/train
ln -sfn /tmp/ds_paper python/examples/nets/photo/data/paper

# the runs: the first alone for a minute (its steps per second undisturbed), then the rest
pids=()
first=1
for run in "$@"; do
    python3 -m matedit.nets.train "python/examples/nets/photo/$run.py" --out "/tmp/runs/$run" \
        --stop-after "$((first ? seconds : seconds - 60))" >"/tmp/runs/$run.log" 2>&1 &
    pids+=($!)
    if [ $first = 1 ]; then sleep 60; first=0; fi
done
for p in "${pids[@]}"; do wait "$p"; done
stamp "training done; chunks synthesised: $(for f in $folders; do echo "$f $(ls $f/chunk-*.json | wc -l)"; done)"
pkill -f matedit.synth
for run in "$@"; do
    tail -3 "/tmp/runs/$run.log"
    cp "/tmp/runs/$run/weights.safetensors" "$out/$run.safetensors"
done
tar -C /tmp/runs -cJf "$out/runs.tar.xz" --exclude='*.pt' --exclude='*.safetensors' .
stamp "done"
