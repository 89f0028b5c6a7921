"""A copy of a make_set.py set whose true light is scaled to the level `matedit edit`'s rule
gives (2.45 times the background's mean luminance, the background leaving out the pixels
within 1 % of the photo's longer side of the object): the light's shape without its level.
Every other file is linked, not copied.

    python rule_light.py --set SET --out SET_RULE
    python evaluate.py --matedit target/release/matedit --set SET_RULE --out OUT --runs edit --known light
"""

import argparse
import glob
import os

import numpy as np
from PIL import Image
from scipy import ndimage

BACKGROUND_GAIN = 2.45  # src/edit/photo/light.rs
LUM = np.array([0.2126, 0.7152, 0.0722])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", required=True)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    for d in sorted(glob.glob(os.path.join(args.set, "[0-9]*/"))):
        out = os.path.join(args.out, os.path.basename(os.path.normpath(d)))
        os.makedirs(out, exist_ok=True)
        for f in os.listdir(d):
            if f != "light.exr" and not os.path.lexists(os.path.join(out, f)):
                os.symlink(os.path.abspath(os.path.join(d, f)), os.path.join(out, f))
        srgb = np.asarray(Image.open(os.path.join(d, "photo.png")).convert("RGB"), np.float64) / 255
        image = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        mask = np.asarray(Image.open(os.path.join(d, "mask.png")).convert("L")) > 127
        edge = max(2, round(0.01 * max(mask.shape)))
        background = (image @ LUM)[~ndimage.binary_dilation(mask, iterations=edge)].mean()
        env = np.array(mi.Bitmap(os.path.join(d, "light.exr")), np.float64)[..., :3]
        rows, cols = env.shape[:2]
        weight = np.sin((np.arange(rows) + 0.5) / rows * np.pi)[:, None] * np.ones((1, cols))
        level = ((env @ LUM) * weight).sum() / weight.sum()
        mi.Bitmap((env * BACKGROUND_GAIN * background / level).astype(np.float32)).write(os.path.join(out, "light.exr"))
        print(f"{os.path.basename(out)}: the true level is {level / (BACKGROUND_GAIN * background):.2f} times the rule's")


if __name__ == "__main__":
    main()
