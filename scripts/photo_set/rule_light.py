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
from scipy import ndimage

from level_features import BACKGROUND_GAIN, light_level, photo_and_mask
from make_set import luminance


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
        image, mask = photo_and_mask(d)
        edge = max(2, round(0.01 * max(mask.shape)))
        background = luminance(image)[~ndimage.binary_dilation(mask, iterations=edge)].mean()
        level, env = light_level(mi, d)
        mi.Bitmap((env * BACKGROUND_GAIN * background / level).astype(np.float32)).write(os.path.join(out, "light.exr"))
        print(f"{os.path.basename(out)}: the true level is {level / (BACKGROUND_GAIN * background):.2f} times the rule's")


if __name__ == "__main__":
    main()
