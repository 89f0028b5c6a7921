#!/usr/bin/env bash
# One session on a lent GPU machine (16 cores, one H100), run from the repository's root:
# the Rust GPU tests on the real GPU, then photo-like samples synthesised on the CPUs while
# the nets train on the GPU from them (resident mode, following the growing folder).
#
# Made ready on the development machine (docs/nets.md, "Training on a GPU"):
#   .dev/it.xz             the release test binary (cargo test --release --no-run --test it), stripped
#   .dev/matedit.so.xz     the Python package's extension (maturin build --release), stripped
#   .dev/data.tar.xz       photo/{train.json, meshes/train, envmaps}: the training spec's inputs
#   .gl/*.deb              the Vulkan loader (the device's README)
# Writes to $OUT: gpu_tests.log, runs.tar.xz (every run's log, run.json, losses.png) and
# each run's weights.
#
#   bash python/examples/nets/photo/device.sh SECONDS RUN...     RUN: a config of this folder
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
xz -dc .dev/it.xz >/tmp/dev/it && chmod +x /tmp/dev/it
cp -r python/matedit/. /tmp/site/matedit/
xz -dc .dev/matedit.so.xz >/tmp/site/matedit/_matedit.abi3.so
tar -C /tmp/dev -xJf .dev/data.tar.xz
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1 PYTORCH_CUDA_ALLOC_CONF=expandable_segments:True
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
stamp "unpacked"

# the synthesis: 12 shards of one process each, one thread each, writing one folder
shards=${SHARDS:-12}
for i in $(seq 0 $((shards - 1))); do
    python3 -c "import matedit; matedit.synth('/tmp/dev/photo/train.json', '/tmp/ds', shard=($i, $shards), threads=1)" \
        >/tmp/runs/synth-$i.log 2>&1 &
done

# the GPU tests meanwhile (the names as .ci/run reruns them)
MATEDIT_REQUIRE_GPU=1 timeout ${TEST_SECONDS:-150} /tmp/dev/it gpu every_backend_gives_the_references_corrections \
    --test-threads 4 >"$out/gpu_tests.log" 2>&1
stamp "GPU tests: exit $? ($(grep -c '\.\.\. ok' "$out/gpu_tests.log") ok, $(grep -c 'FAILED\|panicked' "$out/gpu_tests.log") failed)"
until ls /tmp/ds/chunk-*.json >/dev/null 2>&1; do sleep 1; done
stamp "$(ls /tmp/ds/chunk-*.json | wc -l) chunks so far"
mkdir -p python/examples/nets/photo/data && ln -sfn /tmp/ds python/examples/nets/photo/data/train

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
stamp "training done; $(ls /tmp/ds/chunk-*.json | wc -l) chunks synthesised"
pkill -f matedit.synth
for run in "$@"; do
    tail -3 "/tmp/runs/$run.log"
    cp "/tmp/runs/$run/weights.safetensors" "$out/$run.safetensors"
done
tar -C /tmp/runs -cJf "$out/runs.tar.xz" --exclude='*.pt' --exclude='*.safetensors' .
stamp "done"
