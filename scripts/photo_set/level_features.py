"""Does anything in a photo tell the light's level better than the background's mean?

For each scene of make_set.py's sets, the truth: the level of the light at the object
(light.exr's mean luminance over the sphere, in the photo's units) over the mean luminance
of the background (the pixels off the object and 3 pixels from it). The edit takes the
light at a constant times the background's mean (docs/edit.md, "The light's level"); its
error is this ratio's spread. Candidate statistics of the photo (the background's
percentiles, its part above the object, the object's mean and brightest 2 %, the clipped
fraction, all over the background's mean), one and two at a time, are fitted by least
squares to the log ratio on one set and judged on the other: the log-rms left against the
constant's.

    python level_features.py --fit /tmp/or/tune24 --judge /tmp/or/test24

With `--fit-eval` and `--judge-eval` (evaluate.py's OUT folders for those sets, `--runs edit`,
any `--weights`), the nets' own level joins the statistics: the log of the light the nets
predicted (what `--no-background-light` keeps) over the background's mean, from the factors
each edit's report.json says the light was scaled by to take the background's level.
"""

import argparse
import glob
import itertools
import json
import os

import numpy as np
from PIL import Image
from scipy import ndimage

from make_set import luminance

BACKGROUND_GAIN = 2.45  # src/edit/photo/light.rs: the light over the background's mean


def photo_and_mask(scene_dir):
    """A scene's photo (linear RGB, float64) and its object's mask."""
    srgb = np.asarray(Image.open(os.path.join(scene_dir, "photo.png")).convert("RGB"), np.float64) / 255
    photo = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return photo, np.asarray(Image.open(os.path.join(scene_dir, "mask.png")).convert("L")) > 127


def light_level(mi, scene_dir):
    """The mean luminance over the sphere of a scene's true light (light.exr) and the map."""
    env = np.array(mi.Bitmap(os.path.join(scene_dir, "light.exr")), np.float64)[..., :3]
    rows, cols = env.shape[:2]
    weight = np.sin((np.arange(rows) + 0.5) / rows * np.pi)[:, None] * np.ones((1, cols))
    return (luminance(env) * weight).sum() / weight.sum(), env


def scene_features(mi, d):
    photo, mask = photo_and_mask(d)
    background = ~ndimage.binary_dilation(mask, iterations=3)
    level, _ = light_level(mi, d)
    lum = luminance(photo)
    bg = lum[background]
    first = np.nonzero(mask)[0].min()
    above = lum[:first][background[:first]] if first > 2 else bg
    ratio = lambda v: np.log(v / bg.mean())
    return {"truth": ratio(level), "background mean": np.log(bg.mean()), "median": ratio(np.median(bg)),
            "95th percentile": ratio(np.percentile(bg, 95)), "99.5th percentile": ratio(np.percentile(bg, 99.5)),
            "above the object": ratio(above.mean()), "object mean": ratio(lum[mask].mean()),
            "object's brightest 2 %": ratio(np.percentile(lum[mask], 98)),
            "clipped fraction": (photo.max(-1) > 0.99).mean()}


def nets_level(eval_dir, scene):
    """log(the nets' light / the background's mean) of one scene's edit, or None where the
    edit took its level from a grey card (nothing behind the object)."""
    with open(os.path.join(eval_dir, scene, "edit", "report.json")) as f:
        report = json.load(f)
    if report["light_level_from"] != "background":
        return None
    return float(np.log(BACKGROUND_GAIN) - np.log(luminance(np.array(report["light_factors"]))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fit", required=True, help="the set the fits are made on")
    ap.add_argument("--judge", required=True, help="the set they are judged on")
    ap.add_argument("--fit-eval", help="evaluate.py's OUT for the --fit set: the nets' level joins")
    ap.add_argument("--judge-eval", help="... and for the --judge set")
    args = ap.parse_args()
    if (args.fit_eval is None) != (args.judge_eval is None):
        ap.error("--fit-eval and --judge-eval come together")
    import mitsuba as mi
    mi.set_variant("scalar_rgb")

    def features(set_dir, eval_dir):
        out = []
        for d in sorted(glob.glob(os.path.join(set_dir, "[0-9]*/"))):
            f = scene_features(mi, d)
            if eval_dir:
                f["the nets' level"] = nets_level(eval_dir, os.path.basename(os.path.normpath(d)))
                if f["the nets' level"] is None:
                    continue
            out.append(f)
        return out

    fit, judge = features(args.fit, args.fit_eval), features(args.judge, args.judge_eval)
    y_fit, y_judge = (np.array([f["truth"] for f in fs]) for fs in (fit, judge))
    constant = np.sqrt(((y_judge - y_fit.mean()) ** 2).mean())
    print(f"{len(fit)} scenes fitted, {len(judge)} judged; level over the background's mean: "
          f"median {np.exp(np.median(y_fit)):.2f} and {np.exp(np.median(y_judge)):.2f}")
    print(f"| statistics | log-rms, fitted | log-rms, judged |\n|---|---:|---:|\n| none (a constant) | "
          f"{y_fit.std():.3f} | {constant:.3f} |")
    if args.fit_eval:
        for name, fs in (("fitted", fit), ("judged", judge)):
            miss = [f["the nets' level"] - f["truth"] for f in fs]
            print(f"the nets' level alone, {name}: log-rms {np.sqrt(np.mean(np.square(miss))):.3f}")
    names = [k for k in fit[0] if k != "truth"]
    for combo in itertools.chain(itertools.combinations(names, 1), itertools.combinations(names, 2)):
        x_fit, x_judge = (np.array([[1.0] + [f[k] for k in combo] for f in fs]) for fs in (fit, judge))
        beta = np.linalg.lstsq(x_fit, y_fit, rcond=None)[0]
        rms = lambda x, y: np.sqrt(((y - x @ beta) ** 2).mean())
        print(f"| {', '.join(combo)} | {rms(x_fit, y_fit):.3f} | {rms(x_judge, y_judge):.3f} |")


if __name__ == "__main__":
    main()
