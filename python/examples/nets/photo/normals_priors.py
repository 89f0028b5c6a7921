"""Do simple priors on the nets' normals bring them closer to the truth, with no training?

Runs the nets (mirrored, as `matedit edit` does) on a `matedit synth` folder at their own
size and measures the normals' error (degrees, over the true mask) by distance to the
mask's edge, then with two corrections, each swept:
- the silhouette: within `width` pixels of the edge, the normal blended by up to `beta`
  towards the edge's outward direction in the image plane (z = 0), as on a smooth closed
  object seen edge on;
- the tilt: x and y scaled by k and renormalised (k > 1: less frontal normals).

    python normals_priors.py WEIGHTS DATA [--limit 256]
"""

import argparse
import itertools

import numpy as np
import torch
from scipy import ndimage

from matedit.nets.data import collate, samples
from matedit.nets.model import load, prepare


def angles(a, b):
    a = a / np.linalg.norm(a, axis=-1, keepdims=True).clip(1e-9)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


def edge_geometry(mask):
    """Distance (pixels) of each object pixel to the edge, and the edge's outward direction
    (x right, y up) from a smoothed signed distance."""
    inside = ndimage.distance_transform_edt(mask)
    signed = ndimage.gaussian_filter(inside - ndimage.distance_transform_edt(~mask), 1.5)
    gy, gx = np.gradient(signed)
    out = np.stack([-gx, gy], -1)  # rows grow downwards, y upwards
    return inside, out / np.linalg.norm(out, axis=-1, keepdims=True).clip(1e-9)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("weights")
    ap.add_argument("data")
    ap.add_argument("--limit", type=int, default=256)
    args = ap.parse_args()
    nets = load(args.weights).eval()
    pred, true, masks = [], [], []
    stream = itertools.islice(samples(args.data), args.limit)
    with torch.no_grad():
        while batch := list(itertools.islice(stream, 32)):
            b = collate(batch)
            pred.append(nets(prepare(b["image"], b["mask"]), b["mask"], True)["normals"].numpy())
            true.append(b["normals"].numpy())
            masks.append(b["mask"].numpy())
    p, t, m = np.concatenate(pred), np.concatenate(true), np.concatenate(masks)
    dist, outward = zip(*(edge_geometry(k) for k in m))
    dist, outward = np.stack(dist), np.stack(outward)
    err = angles(p, t)
    print(f"{len(m)} samples: mean {err[m].mean():.2f}, median {np.median(err[m]):.2f} degrees")
    print("| from the edge (pixels) | share of the object | error | true z | the nets' z |\n|---|---:|---:|---:|---:|")
    for lo, hi in [(0, 1.5), (1.5, 3), (3, 6), (6, 12), (12, np.inf)]:
        s = m & (dist > lo) & (dist <= hi)
        print(f"| {lo:g} to {hi:g} | {100 * s.sum() / m.sum():.1f} % | {err[s].mean():.1f} | "
              f"{t[s][:, 2].mean():.2f} | {p[s][:, 2].mean():.2f} |")
    edge = np.concatenate([outward, np.zeros(m.shape + (1,))], -1)
    for width, beta in itertools.product([1.5, 3, 5], [0.3, 0.6, 0.9]):
        a = (beta * np.clip(1 - (dist - 1) / width, 0, 1))[..., None]
        print(f"silhouette, width {width:g}, beta {beta:g}: mean {angles((1 - a) * p + a * edge, t)[m].mean():.2f}")
    for k in [1.1, 1.2, 1.4]:
        e = angles(p * np.array([k, k, 1.0]), t)[m]
        print(f"tilt k {k:g}: mean {e.mean():.2f}, median {np.median(e):.2f}")


if __name__ == "__main__":
    main()
