"""The pictures of docs/edit.md and the README's editing section, made by matedit's commands:

    python python/examples/edit_demo.py MESHES ENVMAP OUT_DIR

Three "photos" (256 x 256 PNGs): held-out meshes of the experiment (docs/nets.md) rendered
by `matedit synth` under ENVMAP (forest.exr, the held-out HDRI) with held-out MERL materials,
the map itself behind them; then `matedit edit` on the first (to gold, and --like the second)
and `matedit grid` on all three. Needs `matedit` on the PATH.
"""

import io
import json
import pathlib
import subprocess
import sys
import tarfile

import numpy as np

PHOTOS = [("armadillo.off", "pvc", 3), ("camel.off", "brass", 5), ("elephant.off", "blue-metallic-paint", 2)]


def run(*args):
    print("+", " ".join(map(str, args)), flush=True)
    subprocess.run(list(map(str, args)), check=True)


def png(path, image):
    from PIL import Image

    x = np.clip(image, 0, 1)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    Image.fromarray((srgb * 255 + 0.5).astype(np.uint8)).save(path)


def main(meshes, envmap, out):
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for mesh, material, seed in PHOTOS:
        name = pathlib.Path(mesh).stem
        spec = {"count": 1, "seed": seed, "image_size": 256, "env_size": "64x128",
                "normals": [{"mesh": str(pathlib.Path(meshes).resolve() / mesh), "views": "upright"}],
                "envs": [{"file": str(pathlib.Path(envmap).resolve())}],
                "materials": [{"preset": material}], "backgrounds": ["env"]}
        (out / f"{name}.json").write_text(json.dumps(spec))
        run("matedit", "synth", out / f"{name}.json", "-o", out / f"ds_{name}")
        with tarfile.open(next((out / f"ds_{name}").glob("*.tar"))) as t:
            get = {m.name.split(".", 1)[1]: m for m in t.getmembers()}
            image = np.load(io.BytesIO(t.extractfile(get["image.npy"]).read()))
        png(out / f"{name}.png", image)
        names.append(out / f"{name}.png")
    run("matedit", "edit", names[0], "--material", "gold", "-o", out / "edit_gold")
    run("matedit", "edit", names[0], "--like", names[1], "-o", out / "edit_like")
    run("matedit", "grid", *names, "-o", out / "grid.png", "--cell", "192")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
