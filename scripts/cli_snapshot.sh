#!/usr/bin/env bash
# A snapshot of what the command line prints and writes, to compare two builds byte for byte
# (a refactor must change neither): `--help` of the binary and of every command, and the
# README's example commands on inputs in the repository and ../shared/data (small sizes
# where the README's take minutes), each output file's SHA-256 in OUTDIR/SHA256SUMS.
#
#   scripts/cli_snapshot.sh OUTDIR BINARY     (a binary named matedit: usage lines show its name)
#   diff -r /tmp/before /tmp/after    # the same text, the same sums
#
# Runs on the CPU path (--device cpu) so that the bytes do not depend on an adapter. Lines
# that hold a time (report.json's "seconds", stderr's "in 1.2 s") are left out of the
# comparison.
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 OUTDIR BINARY" >&2; exit 2; }
repo="$(cd "$(dirname "$0")/.." && pwd)"
out="$(mkdir -p "$1" && cd "$1" && pwd)"
bin="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"
shared="$repo/../shared/data"
work="$out/files"
rm -rf "$work" "$out/help" "$out/stderr"
mkdir -p "$work" "$out/help" "$out/stderr"

commands="render grad info fit-brdf fit transfer grid synth presets"
"$bin" --help >"$out/help/matedit.txt"
"$bin" --version >"$out/help/version.txt"
for c in $commands; do
    "$bin" "$c" --help >"$out/help/$c.txt"
    "$bin" help "$c" >"$out/help/help-$c.txt"
done

n=0
# run NAME ARGS...: the command in $work, its stdout and (timeless) stderr kept; a failure
# is kept too (its exit code), since failing the same way is also "the same"
run() {
    local name="$1"
    shift
    n=$((n + 1))
    local rc=0
    (cd "$work" && "$bin" "$@") >"$out/stderr/$name.stdout" 2>"$out/stderr/$name.err" || rc=$?
    echo "exit $rc" >>"$out/stderr/$name.err"
    sed -i -E 's/[0-9]+(\.[0-9]+)? s\b/T s/g; s/[0-9.]+ samples\/s/R samples\/s/g' "$out/stderr/$name.err"
}

run render-default render -o default.png --device cpu
run render-exr render -o s.exr --sphere 96 --env "$shared/envmaps/sunset.exr" --device cpu
run render-tolerance render -o t.exr --sphere 96 --env "$shared/envmaps/sunset.exr" --tolerance 1e-3 --device cpu
run render-method render -o m.npy --sphere 64 --preset gold --method table32+keep16 --device cpu
run render-png render -o p.png --sphere 64 --preset gold --exposure 1 --tonemap reinhard --device cpu --fov 40
run render-bad render -o bad.txt --device cpu
cat >"$work/scenes.json" <<'EOF'
{"scenes": [{"output": "a.exr", "preset": "gold"}, {"output": "b.npy"}]}
EOF
mkdir -p "$work/renders"
run render-batch render --batch scenes.json -o renders/ --sphere 48 --device cpu
run upstream render -o up.npy --sphere 64 --device cpu
run grad grad -o grads/ --sphere 64 --upstream up.npy --device cpu
run grad-only grad -o grads_ctrl/ --sphere 64 --upstream up.npy --only ctrl --device cpu
run info-exr info s.exr
run info-npy info up.npy
run info-json info grads/d_material.json
run info-png info p.png
run presets presets
run presets-gold presets gold
run fit-brdf fit-brdf --nbrdf "$repo/data/merl/merl_nbrdf.json" --name alum-bronze -o alum.json --lobes 2
run fit-brdf-folder fit-brdf --nbrdf "$repo/data/merl/merl_nbrdf.json" --name alum-bronze -o alum/ --bundle alum-bundle.json --lobes 1
run fit-brdf-many fit-brdf --nbrdf "$repo/data/merl/merl_nbrdf.json" -o all.json
run fit-brdf-no-bundle-folder fit-brdf --nbrdf "$repo/data/merl/merl_nbrdf.json" --bundle missing/b.json
for m in jade clay_studio metal_shiny; do
    run "fit-$m" fit --image "$shared/matcaps/$m.exr" --sphere --steps 40 --work-size 32 --device cpu -o "fits/$m"
done
run fit-env fit --image "$shared/matcaps/jade.exr" --sphere 512 --env "$shared/envmaps/studio.exr" --env-size 8x16 --init gold --steps 20 --work-size 24 --device cpu -o fits/ball
run fit-mask fit --image m.npy --sphere 64 --mask p.png --fit-env 4x8 --steps 10 --device cpu -o fits/masked
run fit-bad fit --image s.exr --normals up.npy --mask p.png --steps 5 --device cpu -o fits/bad
run transfer transfer --shape-light fits/jade --material fits/metal_shiny -o jade_as_metal.png --device cpu
run grid grid fits/jade fits/clay_studio fits/metal_shiny -o grid.png --cell 32 --device cpu
cat >"$work/spec.json" <<EOF
{"count": 6, "seed": 7, "image_size": 16, "env_size": "8x16", "chunk_size": 2,
 "normals": [{"sphere": 16}, {"bumpy": 16}], "envs": ["$shared/envmaps/sunset.exr", "$shared/envmaps/forest.exr"],
 "materials": [{"preset": "gold"}, {"random": "merl"}]}
EOF
run synth synth spec.json -o ds/ --device cpu
run synth-shard synth spec.json -o ds2/ --shard 1/2 --device cpu
run synth-verify synth spec.json -o ds/ --verify --device cpu

# every file written, its sum; report.json without its times
find "$work" -name report.json -exec sed -i -E '/"seconds"/d' {} +
(cd "$work" && find . -type f | LC_ALL=C sort | xargs sha256sum) >"$out/SHA256SUMS"
echo "$n commands; $(wc -l <"$out/SHA256SUMS") files in $out/SHA256SUMS"
