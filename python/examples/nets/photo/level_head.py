"""Can the light net's features tell the light's level over the background, where the
background's mean alone leaves a factor 1.37 either way on path-traced photos?

For each sample of `matedit synth` folders (training and validation) and each scene of
scripts/photo_set's path-traced sets: the target is log(the light's mean luminance over the
sphere / the background's mean luminance), the background being the pixels 2 or more from
the object (the path-traced photos as `matedit edit` shows them to the nets: the square
around the object with a 5 % margin, 128 a side; their light the set's light.exr). The
features: the light net's pooled features and hidden layer, mirrored and averaged, and
its own log level. Ridge regressions on the training folder, judged on the others, beside
`matedit edit`'s rule (2.45 times the whole photo's background mean).

    python level_head.py WEIGHTS --train SYNTH --val SYNTH --sets TUNE TEST
"""

import argparse
import glob
import itertools
import os

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image
from scipy import ndimage

from matedit.nets.data import collate, samples
from matedit.nets.model import load, prepare

LUM = np.array([0.2126, 0.7152, 0.0722])
BACKGROUND_GAIN = 2.45  # src/edit/photo/light.rs


def level(env):
    """The mean luminance over the sphere of a lat-long map (H, W, 3)."""
    h, w = env.shape[:2]
    weight = np.sin((np.arange(h) + 0.5) / h * np.pi)[:, None] * np.ones((1, w))
    return float(((env @ LUM) * weight).sum() / weight.sum())


def background_mean(image, mask, edge=2):
    return float((image @ LUM)[~ndimage.binary_dilation(mask, iterations=edge)].mean())


@torch.no_grad()
def features(nets, image, mask):
    """(B, 769): the light net's pooled features (256) and hidden layer (512), averaged with
    the mirrored image's, and its own log level (over the object's mean)."""
    x = prepare(image, mask)
    g = nets.light.net
    both = []
    for xx, mm in ((x, mask), (x.flip(-1), mask.flip(-1))):
        m = mm.to(xx.dtype)[:, None]
        f = g.enc(torch.cat([xx, m], 1))[-1]
        mf = F.adaptive_avg_pool2d(m, f.shape[-2:])
        pooled = torch.cat([(f * mf).sum((2, 3)) / mf.sum((2, 3)).clamp_min(1e-6), f.mean((2, 3))], 1)
        both.append(torch.cat([pooled, g.head[1](g.head[0](pooled))], 1))
    own = [np.log(level(e)) for e in nets(x, mask, True)["env"].numpy()]
    return np.c_[((both[0] + both[1]) / 2).numpy(), own]


def synth_folder(nets, folder):
    xs, ys = [], []
    stream = samples(folder)
    while batch := list(itertools.islice(stream, 32)):
        b = collate(batch)
        xs.append(features(nets, b["image"], b["mask"]))
        ys += [np.log(level(e) / background_mean(i, m))
               for i, m, e in zip(b["image"].numpy(), b["mask"].numpy(), b["env"].numpy())]
    return np.concatenate(xs), np.array(ys), None


def crop(a, mask, n=128):
    """The square around the mask's bounding box with a 5 % margin, padded with zeros,
    area-averaged to n x n."""
    ys, xs = np.nonzero(mask)
    side = int(np.ceil(max(np.ptp(ys) + 1, np.ptp(xs) + 1) / 0.9))
    y0 = int(round((ys.min() + ys.max() + 1 - side) / 2))
    x0 = int(round((xs.min() + xs.max() + 1 - side) / 2))
    padded = np.pad(a, ((side, side), (side, side)) + ((0, 0),) * (a.ndim - 2))
    c = torch.from_numpy(np.ascontiguousarray(padded[y0 + side:y0 + 2 * side, x0 + side:x0 + 2 * side])).float()
    c = c[None, None] if c.dim() == 2 else c.permute(2, 0, 1)[None]
    r = F.interpolate(c, size=(n, n), mode="area")[0]
    return r.permute(1, 2, 0).numpy() if a.ndim == 3 else r[0].numpy()


def photo_set(nets, mi, set_dir):
    xs, ys, rule = [], [], []
    for d in sorted(glob.glob(os.path.join(set_dir, "[0-9]*/"))):
        srgb = np.asarray(Image.open(os.path.join(d, "photo.png")).convert("RGB"), np.float64) / 255
        image = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        mask = np.asarray(Image.open(os.path.join(d, "mask.png")).convert("L")) > 127
        truth = level(np.array(mi.Bitmap(os.path.join(d, "light.exr")), np.float64)[..., :3])
        small, small_mask = crop(image, mask), crop(mask.astype(np.float64), mask) > 0.5
        xs.append(features(nets, torch.from_numpy(small).float()[None], torch.from_numpy(small_mask)[None]))
        ys.append(np.log(truth / background_mean(small, small_mask)))
        rule.append(np.log(BACKGROUND_GAIN * background_mean(image, mask, 3) / truth))
    return np.concatenate(xs), np.array(ys), np.array(rule)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("weights")
    ap.add_argument("--train", required=True, help="a matedit synth folder the regressions are fitted on")
    ap.add_argument("--val", required=True, help="another, to judge them")
    ap.add_argument("--sets", nargs="+", default=[], help="make_set.py sets (with light.exr) to judge them on")
    args = ap.parse_args()
    nets = load(args.weights).eval()
    data = {"train": synth_folder(nets, args.train), "val": synth_folder(nets, args.val)}
    if args.sets:
        import mitsuba as mi
        mi.set_variant("scalar_rgb")
        data.update({os.path.basename(os.path.normpath(s)): photo_set(nets, mi, s) for s in args.sets})
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))
    print("log(light / background mean): " + ", ".join(
        f"{k} median {np.exp(np.median(y)):.2f} log-std {y.std():.3f}" for k, (_, y, _) in data.items()))
    print("the rule (2.45 x the background's mean): " + ", ".join(
        f"{k} {rms(r):.3f}" for k, (_, _, r) in data.items() if r is not None))
    x_train, y_train, _ = data["train"]
    mu, sd = x_train.mean(0), x_train.std(0) + 1e-6
    print("| features | ridge | " + " | ".join(data) + " |\n|---|---:|" + "---:|" * len(data))
    for name, cols in (("the nets' own level", slice(768, 769)), ("pooled and hidden", slice(0, 768)),
                       ("all", slice(0, 769))):
        for lam in (1, 10, 100, 1000):
            design = lambda x: np.c_[np.ones(len(x)), ((x - mu) / sd)[:, cols]]
            a = design(x_train)
            reg = lam * np.eye(a.shape[1])
            reg[0, 0] = 0
            w = np.linalg.solve(a.T @ a + reg, a.T @ y_train)
            print(f"| {name} | {lam} | " + " | ".join(f"{rms(y - design(x) @ w):.3f}" for x, y, _ in data.values()) + " |")


if __name__ == "__main__":
    main()
