"""A page of predictions (docs/nets/predictions.png): for the first N samples of a held-out
folder, one row each: the input I, the predicted and true normals, the predicted and true
light (tonemapped lat-long maps), the predicted and true material on a sphere under the first
probe light, I' = R(n', m', L'), O' = R(n', m_t, L') and the true edit O = R(n, m_t, L), m_t
the next sample's material.

    python predictions.py WEIGHTS DATA OUT.png [--count N] [--samples I,J,...] [--mirror]

--samples shows those samples (by their place in DATA) instead of the first N; --mirror runs
the nets as `matedit edit` does, averaged with the mirrored image (model.Nets.forward).
"""

import argparse

import numpy as np
import torch
from PIL import Image, ImageDraw

import matedit.nets  # noqa: F401  (sets OMP_WAIT_POLICY before torch's first use)
import matedit.torch
from matedit.nets.data import collate, samples
from matedit.nets.model import load, normalise, prepare, probe_scene, spheres

CELL, GAP = 64, 4
COLUMNS = ["I", "n'", "n", "L'", "L", "m'", "m", "I'", "O'", "O"]


def tone(x: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear RGB to 8-bit sRGB after x / (1 + x) (Reinhard) at the exposure."""
    x = np.clip(x * exposure, 0, None)
    x = x / (1 + x)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return (np.clip(s, 0, 1) * 255 + 0.5).astype(np.uint8)


def cell(rgb8: np.ndarray) -> Image.Image:
    img = Image.fromarray(rgb8)
    return img.resize((CELL, CELL) if img.width == img.height else (CELL, CELL // 2), Image.NEAREST)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("weights")
    ap.add_argument("data")
    ap.add_argument("out")
    ap.add_argument("--count", type=int, default=8)
    ap.add_argument("--samples", help="comma-separated sample numbers to show (default: the first COUNT)")
    ap.add_argument("--mirror", action="store_true")
    a = ap.parse_args()
    nets = load(a.weights).eval()
    if a.samples:
        chosen = [int(i) for i in a.samples.split(",")]
        every = {i: s for i, s in enumerate(samples(a.data)) if i in set(chosen)}
        batch = collate([every[i] for i in chosen])
        a.count = len(chosen)
    else:
        batch = collate([s for _, s in zip(range(a.count + 1), samples(a.data))])
    image, mask = batch["image"], batch["mask"]
    target, s = normalise(image, mask)
    env_t = batch["env"] / s[:, None, None, None]
    probe = probe_scene(32, nets.cfg.env_height, nets.cfg.env_width)
    with torch.no_grad():
        out = nets(prepare(image, mask), mask, a.mirror)
        n_pred = out["normals"] * mask[..., None]
        m_t = batch["ctrl"].roll(-1, 0)  # the next sample's material
        i_p = matedit.torch.render(n_pred, out["env"], out["ctrl"])
        o_p = matedit.torch.render(n_pred, out["env"], m_t)
        o = matedit.torch.render(batch["normals"], env_t, m_t)
        sph_p = spheres(out["ctrl"], probe)[:, 0]
        sph_t = spheres(batch["ctrl"], probe)[:, 0]
    rows = a.count
    width = len(COLUMNS) * (CELL + GAP) + GAP
    height = 16 + rows * (CELL + GAP) + GAP
    page = Image.new("RGB", (width, height), (24, 24, 24))
    draw = ImageDraw.Draw(page)
    for j, name in enumerate(COLUMNS):
        draw.text((GAP + j * (CELL + GAP) + CELL // 2 - 6, 2), name, fill=(230, 230, 230))

    def normals8(n):
        return ((n.numpy() + 1) / 2 * 255 * (n.numpy() ** 2).sum(-1, keepdims=True).clip(0, 1) ** 0.5).astype(np.uint8)

    for i in range(rows):
        m = mask[i].numpy()[..., None]
        tiles = [
            tone(target[i].numpy()),
            normals8(n_pred[i]),
            normals8(batch["normals"][i]),
            tone(out["env"][i].numpy(), 0.5),
            tone(env_t[i].numpy(), 0.5),
            tone(sph_p[i].numpy()),
            tone(sph_t[i].numpy()),
            tone(i_p[i].numpy() * m),
            tone(o_p[i].numpy() * m),
            tone(o[i].numpy() * m),
        ]
        y = 16 + GAP + i * (CELL + GAP)
        for j, t in enumerate(tiles):
            c = cell(t)
            page.paste(c, (GAP + j * (CELL + GAP), y + (CELL - c.height) // 2))
    page.save(a.out)
    print(f"wrote {a.out} ({rows} samples)")


if __name__ == "__main__":
    main()
