#!/usr/bin/env bash
# Makes ready, on the development machine, what device.sh takes to a lent GPU machine; run
# from the repository's root (docs/nets.md, "Training on a GPU"):
#
#   bash python/examples/nets/photo/prepare.sh MESHES ENVMAPS
#
# MESHES: CGAL's meshes (docs/shapes.md: Debian's libcgal-demo); ENVMAPS: the 15 HDRIs of
# ../shared/data/envmaps_more. Writes, kept out of git by .git/info/exclude:
#   .dev/it.xz           the release test binary, stripped (the GPU tests)
#   .dev/matedit.so.xz   the Python package's extension, release, stripped
#   .dev/data.tar.xz     photo/{meshes/train, envmaps}: train.json's inputs (the HDRIs it names)
#   .gl/*.deb            the Vulkan loader and its neighbours (the device's README)
# Then one run on the device, carrying .dev and .gl:
#   bash python/examples/nets/photo/device.sh SECONDS RUN...
set -euo pipefail
[ $# = 2 ] || { echo "usage: $0 MESHES ENVMAPS" >&2; exit 2; }
meshes=$(realpath "$1")
envmaps=$(realpath "$2")
t0=$SECONDS
mkdir -p .dev .gl
for d in /.dev/ /.gl/; do grep -qxF "$d" .git/info/exclude || echo "$d" >>.git/info/exclude; done

# the GPU tests (cargo builds the binary beside them: split.py below runs it)
it=$(cargo test --locked --release --no-run --test it --message-format=json |
    python3 -c 'import json, sys
print([m["executable"] for m in map(json.loads, sys.stdin)
       if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "it" and m.get("executable")][-1])')
strip -o .dev/it "$it"
xz -f -T2 .dev/it
echo "prepare: .dev/it.xz ($((SECONDS - t0)) s)"

# the Python package's extension
cargo build --locked --release -p matedit-python
strip -o .dev/matedit.so target/release/lib_matedit.so
xz -f -T2 .dev/matedit.so
echo "prepare: .dev/matedit.so.xz ($((SECONDS - t0)) s)"

# the training meshes by the paper experiment's fixed split, and the HDRIs
site=$(mktemp -d)
trap 'rm -rf "$site"' EXIT
cp -r python/matedit "$site/"
cp target/release/lib_matedit.so "$site/matedit/_matedit.abi3.so"
(cd python/examples/nets/paper &&
    PATH="$PWD/../../../../target/release:$PATH" PYTHONPATH="$site" python3 split.py "$meshes")
mkdir -p "$site/photo/meshes" "$site/photo/envmaps"
cp -r python/examples/nets/paper/meshes/train "$site/photo/meshes/"
for f in $(python3 -c 'import json, sys
print(*(e["file"] for e in json.load(open(sys.argv[1]))["envs"] if "file" in e))' python/examples/nets/photo/train.json); do
    cp "$envmaps/$(basename "$f")" "$site/photo/$f"
done
tar -C "$site" -cJf .dev/data.tar.xz photo
echo "prepare: .dev/data.tar.xz, $(ls "$site/photo/meshes/train" | wc -l) training meshes, $(ls "$site/photo/envmaps" | wc -l) HDRIs ($((SECONDS - t0)) s)"

# the Vulkan loader, for a machine that has none (device.sh unpacks it only then)
o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64)
mkdir -p /tmp/amd64/partial
apt-get "${o[@]}" update -qq
(cd .gl && apt-get "${o[@]}" download -qq libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
ls -la .dev .gl
echo "prepare: done in $((SECONDS - t0)) s"
