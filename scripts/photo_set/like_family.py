"""Does `matedit edit --like` read a material from a photo of a sphere into the right family?

Each swatch material of make_set.py (gold, copper, ..., black-rubber) is path traced by
Mitsuba 3 on a unit sphere under each HDRI of a split, exposed as make_set.py exposes its
swatches (a white diffuse sphere there has mean 0.5). matedit reads the material from that
photo (`edit SWATCH --like SWATCH`, the sphere's mask given: material.json), renders it on
a sphere under a uniform white light (radiance 1), and Mitsuba renders the true material
the same way. Under a uniform white light a sphere's mean colour is the material's albedo
as seen from the camera: its lightness and hue, what tells black plastic from grey and gold
from cream. The two are compared in CIELAB (D65): the read material is in the right
family when Delta E 1976 <= 20 (a colour of the same name; black against mid grey is
about 50, gold against cream about 35). Gloss is not measured: a uniform light shows a
material's colour, not the size of its highlight.

Writes OUT/results.json, OUT/results.md (a table per material: true and read L*a*b*,
Delta E median and worst over the maps, how many in the family) and OUT/sheet.png (per
material: the true sphere under the uniform light, then the read one from each map's
photo, then the photos).

    python like_family.py --matedit target/release/matedit --out /tmp/like [--split tune] [--weights W] [--maps 4]

The swatches and the true spheres are kept in OUT and reused by a later run into the same
folder (they do not depend on matedit): a second binary or weights cost only the reads.

`--known-light` reads each material as the layer fits it under the swatch's true light and
normals instead (`matedit fit --env light.exr --normals normals.npy`, the light as
make_set.py's swatch_light.exr: what the layer can tell of the material when nothing else
is guessed); `--known-light edit` as `edit --like` does with the true light given
(`--like-env light.exr`) and the nets' normals.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_set import (SPLITS, SWATCHES, bsdf, grey_card_exposure, layer_light, load_map, render,  # noqa: E402
                      save_png, swatch_dict, to_srgb8, true_normals, white_balance, white_sphere)

FAMILY_DELTA_E = 20.0
SIDE = 128  # the swatch photos' size
ALBEDO_SIDE = 64  # the uniform-light spheres' size


# -----------------------------------------------------------------------------
# colour

def lab(rgb):
    """CIELAB (D65 white = linear RGB (1, 1, 1)) of a linear sRGB colour."""
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = (m @ rgb) / (m @ np.ones(3))
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def disc(n):
    """The pixels of a unit sphere filling an n x n orthographic image."""
    c = (np.arange(n) + 0.5) / n * 2 - 1
    return c[None, :] ** 2 + c[:, None] ** 2 < 1


# -----------------------------------------------------------------------------
# Mitsuba: the swatches and the true materials under a uniform light

def swatch_scene(envmap, seed):
    return {"seed": seed, "swatch_envmap": envmap, "swatch_envmap_yaw": float(seed * 47 % 360)}


def swatch(mi, material, envmap, seed, work, balance_error=None):
    photo_png, mask_png = os.path.join(work, "swatch.png"), os.path.join(work, "mask.png")
    if os.path.exists(photo_png) and os.path.exists(mask_png):
        return np.asarray(Image.open(photo_png)), np.asarray(Image.open(mask_png)) > 127
    scene = swatch_scene(envmap, seed)
    photo = render(mi, swatch_dict(mi, scene, SIDE, 64, bsdf(material)))
    mask = render(mi, swatch_dict(mi, scene, SIDE, 16, None))[..., 0] > 0.5
    white = white_sphere(mi, scene)
    gains = np.ones(3) if balance_error is None else white_balance(white, [seed, 2], balance_error)
    photo = to_srgb8(photo * gains * grey_card_exposure(white, gains))
    save_png(photo_png, photo)
    save_png(mask_png, (mask * 255).astype(np.uint8))
    return photo, mask


def true_albedo(mi, material, work):
    """The material on a sphere under a uniform white light: (mean linear RGB, the image)."""
    path = os.path.join(work, "true.npz")
    if os.path.exists(path):
        z = np.load(path)
        return z["mean"], z["image"]
    d = swatch_dict(mi, {"seed": 0, "swatch_envmap": "", "swatch_envmap_yaw": 0}, ALBEDO_SIDE, 256, bsdf(material))
    d["env"] = {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
    image = render(mi, d)
    mask = render(mi, swatch_dict(mi, {"seed": 0}, ALBEDO_SIDE, 16, None))[..., 0] > 0.5
    np.savez(path, mean=image[mask].mean(0), image=image)
    return image[mask].mean(0), image


def swatch_truth(mi, material, envmap, seed, work, balance_error=None):
    """The swatch's true light (as make_set.py's swatch_light.exr) and normals, written to
    work/light.exr and work/normals.npy (kept when there)."""
    light, normals = os.path.join(work, "light.exr"), os.path.join(work, "normals.npy")
    if not (os.path.exists(light) and os.path.exists(normals)):
        scene = swatch_scene(envmap, seed)
        mask = render(mi, swatch_dict(mi, scene, SIDE, 16, None))[..., 0] > 0.5
        np.save(normals, true_normals(mi, swatch_dict(mi, scene, SIDE, 16, bsdf(material)), np.eye(3), mask))
        white = white_sphere(mi, scene)
        gains = np.ones(3) if balance_error is None else white_balance(white, [seed, 2], balance_error)
        scale = gains * grey_card_exposure(white, gains)
        mi.Bitmap(layer_light(load_map(mi, envmap), scene["swatch_envmap_yaw"], np.eye(3), scale)).write(light)
    return light, normals


# -----------------------------------------------------------------------------
# matedit: the material read from a swatch, under the same light

def read_albedo(binary, photo_png, mask_png, work, extra, known=None):
    """The material matedit reads from the swatch (`edit --like`, or with `known` = (light,
    normals, "fit") `fit` under them, with (light, normals, "edit") `edit --like
    --like-env`) on a sphere under a uniform white light: (mean, image)."""
    out = os.path.join(work, "edit" if known is None else known[2])
    if known is None or known[2] == "edit":
        cmd = [binary, "edit", photo_png, "--like", photo_png, "--mask", mask_png, "--like-mask", mask_png,
               "-o", out, "--device", "cpu", *extra] + ([] if known is None else ["--like-env", known[0]])
    else:
        cmd = [binary, "fit", "--image", photo_png, "--mask", mask_png, "--env", known[0], "--env-size", "16x32",
               "--normals", known[1], "-o", out, "--device", "cpu"]
    subprocess.run(cmd, check=True, capture_output=True)
    white = os.path.join(work, "white.npy")
    np.save(white, np.ones((16, 32, 3), np.float32))
    image_path = os.path.join(work, "read.npy")
    subprocess.run([binary, "render", "--material", os.path.join(out, "material.json"), "--env", white,
                    "--env-size", "16x32", "--sphere", str(ALBEDO_SIDE), "--device", "cpu", "-o", image_path],
                   check=True, capture_output=True)
    image = np.load(image_path)
    return image[disc(ALBEDO_SIDE)].mean(0), image


# -----------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--matedit", required=True, help="the matedit binary")
    ap.add_argument("--out", required=True)
    ap.add_argument("--weights", help="the nets' weights (default: the built-in ones)")
    ap.add_argument("--split", choices=sorted(SPLITS), default="test", help="whose HDRIs (make_set.py's splits)")
    ap.add_argument("--maps", type=int, default=8, help="how many of the split's HDRIs")
    ap.add_argument("--white-balance", type=float, metavar="ERROR",
                    help="balance each swatch for its light, as make_set.py's --white-balance (use a new OUT)")
    ap.add_argument("--extra", default="", help="more options for `matedit edit`, e.g. \"--like-sphere\"")
    ap.add_argument("--known-light", nargs="?", const="fit", choices=["fit", "edit"],
                    help="read each material under the swatch's true light: by `matedit fit` with its true normals "
                         "(fit, the default), or by `edit --like --like-env` with the nets' (edit)")
    args = ap.parse_args()
    if args.white_balance is not None and not args.white_balance >= 0:
        ap.error(f"--white-balance {args.white_balance}: the error is a spread, 0 or more")
    import mitsuba as mi
    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception:  # no usable libLLVM: the scalar variant gives the same images, slower
        mi.set_variant("scalar_rgb")
    os.makedirs(args.out, exist_ok=True)
    extra = (["--weights", args.weights] if args.weights else []) + args.extra.split()
    maps = SPLITS[args.split][1][: args.maps]
    t0 = time.time()
    results, rows = {}, []
    for mi_index, (name, material) in enumerate(SWATCHES.items()):
        os.makedirs(os.path.join(args.out, name), exist_ok=True)
        truth, truth_image = true_albedo(mi, material, os.path.join(args.out, name))
        r = {"true_rgb": truth.tolist(), "true_lab": lab(truth).tolist(), "maps": {}}
        row = [truth_image]
        photos = []
        for k, envmap in enumerate(maps):
            work = os.path.join(args.out, name, envmap)
            os.makedirs(work, exist_ok=True)
            photo, mask = swatch(mi, material, envmap, 100 * mi_index + k, work, args.white_balance)
            known = (*swatch_truth(mi, material, envmap, 100 * mi_index + k, work, args.white_balance),
                     args.known_light) if args.known_light else None
            got, got_image = read_albedo(args.matedit, os.path.join(work, "swatch.png"), os.path.join(work, "mask.png"),
                                         work, extra, known)
            delta = float(np.linalg.norm(lab(got) - lab(truth)))
            r["maps"][envmap] = {"read_rgb": got.tolist(), "read_lab": lab(got).tolist(), "delta_e": delta}
            row.append(got_image)
            photos.append(photo)
        deltas = [m["delta_e"] for m in r["maps"].values()]
        r.update(delta_e_median=float(np.median(deltas)), delta_e_worst=max(deltas),
                 in_family=sum(d <= FAMILY_DELTA_E for d in deltas))
        results[name] = r
        rows.append((row, photos))
        print(f"{name:20s} dE median {r['delta_e_median']:5.1f} worst {r['delta_e_worst']:5.1f} "
              f"in family {r['in_family']}/{len(maps)} ({time.time() - t0:.0f} s)", flush=True)

    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"split": args.split, "maps": maps, "weights": args.weights or "built-in", "known_light": args.known_light,
                   "family_delta_e": FAMILY_DELTA_E,
                   "materials": results}, f, indent=1)
    lines = [f"{'Read under the true light (' + args.known_light + '); ' if args.known_light else ''}Weights: {args.weights or 'built-in'}; maps: {', '.join(maps)}; in the family: Delta E <= {FAMILY_DELTA_E:g}.", "",
             "| material | true L\\* a\\* b\\* | read L\\* a\\* b\\* (median) | Delta E median | worst | in the family |",
             "|---|---|---|---:|---:|---:|"]
    fmt = lambda v: " ".join(f"{x:.0f}" for x in v)
    for name, r in results.items():
        med = np.median([m["read_lab"] for m in r["maps"].values()], axis=0)
        lines.append(f"| {name} | {fmt(r['true_lab'])} | {fmt(med)} | {r['delta_e_median']:.1f} | "
                     f"{r['delta_e_worst']:.1f} | {r['in_family']}/{len(maps)} |")
    total = sum(r["in_family"] for r in results.values())
    lines.append(f"| **all** | | | {np.median([m['delta_e'] for r in results.values() for m in r['maps'].values()]):.1f} | "
                 f"{max(r['delta_e_worst'] for r in results.values()):.1f} | {total}/{len(maps) * len(results)} |")
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))

    # the sheet: per material, the true sphere, the read ones, then the photos (half size)
    s = ALBEDO_SIDE
    sheet = np.zeros((len(rows) * s, (1 + 2 * len(maps)) * s, 3), np.uint8)
    for i, (row, photos) in enumerate(rows):
        for j, image in enumerate(row):
            sheet[i * s:(i + 1) * s, j * s:(j + 1) * s] = to_srgb8(image)
        for j, photo in enumerate(photos):
            small = np.asarray(Image.fromarray(photo).resize((s, s), Image.BILINEAR))
            sheet[i * s:(i + 1) * s, (1 + len(maps) + j) * s:(2 + len(maps) + j) * s] = small
    save_png(os.path.join(args.out, "sheet.png"), sheet)


if __name__ == "__main__":
    main()
