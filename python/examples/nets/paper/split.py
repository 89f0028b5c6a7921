"""The held-out parts of the paper experiment (docs/nets.md, "The experiment"), by fixed rules:

    python split.py MESHES_FOLDER [ENVMAPS_FOLDER]

`matedit` must be on the PATH. MESHES_FOLDER: e.g. the CGAL meshes (docs/shapes.md says how to get them); ENVMAPS_FOLDER
holds forest.exr, studio.exr and sunset.exr (the project's CC0 HDRIs, ../shared/data/envmaps),
copied to envmaps/. Give it only for this folder's specs: envmaps_more has other images of
the same three names, and the paper's splits drawn with those are other splits.

- meshes: grouped by the leading letters of their names (cube, cube-meshed and cube4-shuffled
  are one group, so no variant of a held-out mesh is trained on); every fourth group in
  sorted order is held out. Copies those that
  `matedit normals` draws into meshes/train and meshes/test here.
- materials: every third of the 90 fitted MERL presets (index 2, 5, 8, ...) is held out;
  `held_out_materials()` lists them for the specs and the configs.
- procedural shapes: torus and extrusion are held out (set in the specs), so are unions and
  `random` (which draw every kind).
- lights: forest.exr is held out (set in the specs).
"""

import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

MESH_TYPES = {".off", ".ply", ".stl", ".obj", ".gltf", ".glb"}


def held_out_materials() -> list[str]:
    import matedit

    return [n for i, n in enumerate(matedit.presets()[:90]) if i % 3 == 2]


def group(name: str) -> str:
    return re.match(r"[a-z]*", name.lower()).group(0) or name.lower()


def loads(path: pathlib.Path, tmp: str) -> bool:
    """Whether `matedit normals` draws the file (a point cloud has no triangles)."""
    cmd = ["matedit", "normals", "--mesh", str(path), "--size", "8", "-o", f"{tmp}/n.npy"]
    return subprocess.run(cmd, capture_output=True).returncode == 0


def main(folder: str, envmaps: str | None) -> None:
    if envmaps is not None:
        out = pathlib.Path(__file__).parent / "envmaps"
        out.mkdir(exist_ok=True)
        for name in ("forest.exr", "studio.exr", "sunset.exr"):
            shutil.copyfile(pathlib.Path(envmaps) / name, out / name)
    files = sorted(p for p in pathlib.Path(folder).iterdir() if p.suffix.lower() in MESH_TYPES)
    with tempfile.TemporaryDirectory() as tmp:
        files = [p for p in files if loads(p, tmp)]
    groups = sorted({group(p.stem) for p in files})
    test_groups = set(groups[3::4])
    here = pathlib.Path(__file__).parent
    for split in ("train", "test"):
        out = here / "meshes" / split
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir(parents=True)
        chosen = [p for p in files if (group(p.stem) in test_groups) == (split == "test")]
        for p in chosen:
            shutil.copyfile(p, out / p.name)
        print(f"meshes/{split}: {len(chosen)} files")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2] if len(sys.argv) == 3 else None)
