"""Measure `matedit edit` on the photo-like set that make_set.py renders.

For each scene (a folder with photo.png, mask.png, edit_true.png, swatch.png,
swatch_mask.png, meta.json), over the true mask's pixels, on sRGB values in [0, 1]:

    own     edit photo.png --like photo.png --mask mask.png   PSNR(edit, photo): the photo's
            own material given back; ideally the photo comes back
    edit    edit photo.png --like swatch.png --mask mask.png  PSNR(edit, edit_true), beside
            the baseline PSNR(photo, edit_true) (no edit at all); gain = the difference
    nomask  edit photo.png --like swatch.png                  IoU of the mask the edit found
    box     the same with --box X0,Y0,X1,Y1 from meta.json     (where the binary has --box)

The --like photo's mask is given with --like-mask where the binary has it, else as the
alpha of a PNG copy. A run that exits 2 with a one-line message is "refused" (counted, not
scored). Writes OUT/results.json (per scene) and OUT/results.md (a table, median, worst,
mean). `--runs edit` runs only the edit (any of own, edit, nomask, box); `--like-true`
reads the edit's material from edit_true.png instead of the swatch (the same shape, light
and camera: what the rest of the pipeline gives when the material is read as well as it
can be). `--known normals,light,material` gives the edit run what make_set.py knows of the
scene: its true normals (`--normals normals.npy`), its true light (`--env light.exr`), the
material fitted to the swatch under the swatch's true light and normals (`matedit fit`,
then `--material` in place of `--like`): what each of the nets' guesses costs the edit.

    python evaluate.py --matedit target/release/matedit --set /work/photo_set/test --out /tmp/eval
"""

import argparse
import json
import os
import shlex
import statistics
import subprocess
import time

import numpy as np
from PIL import Image

# -----------------------------------------------------------------------------
# metrics

def psnr(a, b, mask):
    """PSNR in dB of a against b (H x W x 3, values in [0, 1]) over the mask's pixels."""
    mse = float(np.mean((a[mask] - b[mask]) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1 / mse)


def iou(a, b):
    """Intersection over union of two boolean masks (1 if both are empty)."""
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def load_rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255


def load_mask(path):
    return np.asarray(Image.open(path).convert("L")) > 127


# -----------------------------------------------------------------------------
# running the binary

def options_of(binary):
    """The long options that `matedit edit --help` lists."""
    text = subprocess.run([binary, "edit", "--help"], capture_output=True, text=True).stdout
    return {w.strip(",").split("=")[0] for w in text.split() if w.startswith("--")}


def with_alpha(rgb_path, mask_path, out_path):
    """A PNG copy of the image whose alpha is the mask (a PNG's alpha is its mask)."""
    rgb = Image.open(rgb_path).convert("RGB")
    rgb.putalpha(Image.open(mask_path).convert("L"))
    rgb.save(out_path)
    return out_path


def run_edit(binary, photo, like, out, extra, like_mask=None, mask=None, box=None, material=None):
    """Runs one edit to the material of photo `like`, or to the material file `material`;
    returns (status, report or None, message). Status is "ok", "refused" (exit 2, a
    one-line message) or "error"."""
    cmd = [binary, "edit", photo, "-o", out] + (["--material", material] if material else ["--like", like])
    if like_mask:
        cmd += ["--like-mask", like_mask]
    if mask:
        cmd += ["--mask", mask]
    if box:
        cmd += ["--box", ",".join(str(v) for v in box)]
    cmd += extra
    t = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.time() - t
    message = last_line(p.stderr)
    if p.returncode == 0:
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
        report["wall_seconds"] = wall
        return "ok", report, message
    status = "refused" if p.returncode == 2 else "error"
    return status, None, f"exit {p.returncode}: {message}"


def last_line(text):
    lines = [l for l in text.strip().splitlines() if l.strip()]
    return lines[-1] if lines else ""


def known_material(binary, scene_dir, out, device):
    """The swatch's material as the layer fits it under the swatch's true light (at the
    nets' 16 x 32) and normals (make_set.py's swatch_light.exr, swatch_normals.npy): the
    path of out/material.json (kept from an earlier run when there), or None with a
    message. `device`: the edits' --device, if any."""
    path = lambda name: os.path.join(scene_dir, name)
    cmd = [binary, "fit", "--image", path("swatch.png"), "--normals", path("swatch_normals.npy"),
           "--mask", path("swatch_mask.png"), "--env", path("swatch_light.exr"), "--env-size", "16x32",
           "-o", out] + device
    material = os.path.join(out, "material.json")
    if os.path.isfile(material):  # fitted before: kept, as the fit is the slow part
        return material, ""
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode:
        return None, f"fit: exit {p.returncode}: {last_line(p.stderr)}"
    return material, ""


def known_args(scene_dir, known):
    """The edit's arguments that give it the scene's true normals and light."""
    args = []
    if "normals" in known:
        args += ["--normals", os.path.join(scene_dir, "normals.npy")]
    if "light" in known:
        args += ["--env", os.path.join(scene_dir, "light.exr")]
    return args


# -----------------------------------------------------------------------------
# one scene

def evaluate_scene(binary, scene_dir, out, extra, options, runs=("own", "edit", "nomask", "box"), like_true=False,
                   known=(), fits=None):
    with open(os.path.join(scene_dir, "meta.json")) as f:
        meta = json.load(f)
    path = lambda name: os.path.join(scene_dir, name)
    photo, truth, mask = load_rgb(path("photo.png")), load_rgb(path("edit_true.png")), load_mask(path("mask.png"))
    os.makedirs(out, exist_ok=True)
    if "--like-mask" in options:
        own_like, own_mask = path("photo.png"), path("mask.png")
        swatch_like, swatch_mask = path("swatch.png"), path("swatch_mask.png")
    else:
        own_like = with_alpha(path("photo.png"), path("mask.png"), os.path.join(out, "photo_masked.png"))
        swatch_like = with_alpha(path("swatch.png"), path("swatch_mask.png"), os.path.join(out, "swatch_masked.png"))
        own_mask = swatch_mask = None
    if like_true:
        swatch_like, swatch_mask = path("edit_true.png"), path("mask.png")
    r = {
        "scene": os.path.basename(os.path.normpath(scene_dir)),
        "seed": meta["seed"],
        "object": meta["object"],
        "material": meta["material"]["type"],
        "edit_material": meta["edit_material"]["name"],
        "envmap": meta["envmap"],
        "object_pixels": int(mask.sum()),
        "baseline_psnr": psnr(photo, truth, mask),
    }

    if "own" in runs:
        status, report, message = run_edit(binary, path("photo.png"), own_like, os.path.join(out, "own"), extra,
                                           like_mask=own_mask, mask=path("mask.png"))
        r["own_status"] = status
        if status == "ok":
            r["own_psnr"] = psnr(load_rgb(os.path.join(out, "own", "edit.png")), photo, mask)
            r["own_seconds"] = report["seconds"]
        else:
            r["own_message"] = message

    if "edit" in runs:
        material, message = None, ""
        if "material" in known:
            device = extra[extra.index("--device"):][:2] if "--device" in extra else []
            material, message = known_material(binary, scene_dir, os.path.join(fits or out, "known_material"), device)
        if "material" in known and material is None:
            status = "error"
        else:
            status, report, message = run_edit(binary, path("photo.png"), swatch_like, os.path.join(out, "edit"),
                                               extra + known_args(scene_dir, known), like_mask=swatch_mask,
                                               mask=path("mask.png"), material=material)
        r["edit_status"] = status
        if status == "ok":
            r["edit_psnr"] = psnr(load_rgb(os.path.join(out, "edit", "edit.png")), truth, mask)
            r["gain"] = r["edit_psnr"] - r["baseline_psnr"]
            r["edit_seconds"] = report["seconds"]
        else:
            r["edit_message"] = message

    variants = [("nomask", None)] if "nomask" in runs else []
    if "--box" in options and "box" in runs:
        variants.append(("box", meta["box"]))
    for name, box in variants:
        status, report, message = run_edit(binary, path("photo.png"), swatch_like, os.path.join(out, name), extra,
                                           like_mask=swatch_mask, box=box)
        r[f"{name}_status"] = status
        if status == "ok":
            r[f"{name}_iou"] = iou(load_mask(os.path.join(out, name, "mask.png")), mask)
            r[f"{name}_seconds"] = report["seconds"]
        else:
            r[f"{name}_message"] = message
    return r


# -----------------------------------------------------------------------------
# the summary

FIGURES = [  # (key, column title, format)
    ("own_psnr", "own PSNR", "{:.2f}"),
    ("baseline_psnr", "photo vs true", "{:.2f}"),
    ("edit_psnr", "edit vs true", "{:.2f}"),
    ("gain", "gain", "{:+.2f}"),
    ("nomask_iou", "IoU no mask", "{:.3f}"),
    ("box_iou", "IoU box", "{:.3f}"),
]


def cell(r, key, fmt):
    if key in r:
        return fmt.format(r[key])
    status = r.get(key.rsplit("_", 1)[0] + "_status") if key != "gain" else r.get("edit_status")
    return status if status in ("refused", "error") else "-"


def summary(results, figures):
    """Median and worst (lowest) of each figure over the scenes that have it."""
    out = {}
    for key, _, _ in figures:
        values = [r[key] for r in results if key in r]
        if values:
            out[key] = {"median": statistics.median(values), "worst": min(values),
                        "mean": statistics.fmean(values), "n": len(values)}
    for name in ("own", "edit", "nomask", "box"):
        statuses = [r[f"{name}_status"] for r in results if f"{name}_status" in r]
        if statuses:
            out[f"{name}_refused"] = statuses.count("refused")
            out[f"{name}_errors"] = statuses.count("error")
    seconds = [r["edit_seconds"]["total"] for r in results if "edit_seconds" in r]
    if seconds:
        out["edit_total_seconds_median"] = statistics.median(seconds)
    return out


def markdown(results, summ, figures, header):
    cols = ["scene", "object", "material", "edit to"] + [title for _, title, _ in figures] + ["edit s"]
    lines = [header, "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in results:
        secs = f"{r['edit_seconds']['total']:.1f}" if "edit_seconds" in r else "-"
        row = [r["scene"], r["object"], r["material"], r["edit_material"]]
        row += [cell(r, key, fmt) for key, _, fmt in figures] + [secs]
        lines.append("| " + " | ".join(row) + " |")
    for stat in ("median", "worst", "mean"):
        row = [f"**{stat}**", "", "", ""]
        row += [fmt.format(summ[key][stat]) if key in summ else "-" for key, _, fmt in figures]
        row.append(f"{summ['edit_total_seconds_median']:.1f}" if stat == "median" and "edit_total_seconds_median" in summ else "")
        lines.append("| " + " | ".join(row) + " |")
    counts = [f"{name}: {summ[name + '_refused']} refused, {summ[name + '_errors']} errors"
              for name in ("own", "edit", "nomask", "box") if name + "_refused" in summ]
    lines += ["", "PSNR in dB over the true mask (sRGB in [0, 1]); gain = edit vs true - photo vs true; "
              "IoU of the mask the edit found; edit s = report.json's total seconds of the edit run.",
              "Runs that did not finish: " + "; ".join(counts) + "."]
    return "\n".join(lines) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--matedit", required=True, help="the matedit binary")
    p.add_argument("--set", required=True, help="folder of scene folders (make_set.py --out)")
    p.add_argument("--out", required=True, help="folder for the edits and results.{json,md}")
    p.add_argument("--extra", default="", help='arguments appended to every edit, e.g. "--steps 50"')
    p.add_argument("--runs", default="own,edit,nomask,box", help="which runs, of own, edit, nomask, box")
    p.add_argument("--like-true", action="store_true", help="read the edit's material from edit_true.png")
    p.add_argument("--fits", help="with --known material: keep the swatches' fits in FITS/NNN (reused when there) "
                   "instead of OUT/NNN")
    p.add_argument("--known", default="", help="what the edit run is given of the truth: any of normals, light, "
                   "material (make_set.py's normals.npy, light.exr, and the swatch fitted under its true light)")
    args = p.parse_args()
    runs = args.runs.split(",")
    if not set(runs) <= {"own", "edit", "nomask", "box"}:
        p.error(f"--runs {args.runs}: each run is one of own, edit, nomask, box")
    known = [k for k in args.known.split(",") if k]
    if not set(known) <= {"normals", "light", "material"}:
        p.error(f"--known {args.known}: each is one of normals, light, material")
    if "material" in known and args.like_true:
        p.error("--known material and --like-true each say where the material comes from: give one")

    binary = os.path.abspath(args.matedit)
    options = options_of(binary)
    extra = shlex.split(args.extra)
    scenes = sorted(d for d in os.listdir(args.set) if os.path.isfile(os.path.join(args.set, d, "meta.json")))
    wanted = {"own_psnr": "own", "edit_psnr": "edit", "gain": "edit", "nomask_iou": "nomask", "box_iou": "box"}
    figures = [f for f in FIGURES if wanted.get(f[0], "edit") in runs and (f[0] != "box_iou" or "--box" in options)]
    results = []
    for name in scenes:
        r = evaluate_scene(binary, os.path.join(args.set, name), os.path.join(args.out, name), extra, options,
                           runs, args.like_true, known, args.fits and os.path.join(args.fits, name))
        results.append(r)
        print(" ".join([name] + [f"{t}={cell(r, k, f)}" for k, t, f in figures]))
    summ = summary(results, figures)
    config = {"matedit": binary, "set": os.path.abspath(args.set), "extra": extra, "runs": runs,
              "like_true": args.like_true, "known": known,
              "like_mask": "--like-mask" in options, "box": "--box" in options}
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        data = {"config": config, "summary": summ, "scenes": results}
        # strict JSON: an infinite PSNR (identical images) becomes null
        json.dump(json.loads(json.dumps(data), parse_constant=lambda c: None), f, indent=1)
        f.write("\n")
    header = (f"# matedit edit on {args.set} ({len(results)} scenes{', extra: ' + args.extra if args.extra else ''}"
              f"{', known: ' + args.known if known else ''})")
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(markdown(results, summ, figures, header))
    print(markdown(results, summ, figures, header))


if __name__ == "__main__":
    main()
