"""Test data for the Rust port of the networks (`matedit::nets`, tests/it/nets.rs): a small
`Nets(NetsConfig(width=8, levels=2, env_height=8, env_width=16))` of a fixed seed, its
weights as `matedit.nets.save` writes them, and a few inputs with PyTorch's predictions.

    PYTHONPATH=python python python/examples/nets/parity_data.py [OUT_DIR]

writes OUT_DIR/weights.safetensors and OUT_DIR/parity.safetensors (default tests/data/nets).
parity.safetensors holds, per case C:
  C.image (H, W, 3) float32, linear RGB; C.mask_in (H, W) uint8 where the case gives a mask;
  C.normals (H, W, 3), C.mask (H, W) uint8, C.mask_prob (H, W), C.env (H_L, W_L, 3)
  float32 and C.ctrl (108,) float64: `Nets.predict`'s outputs, and the foreground
  probability of the pass that decided the mask (the pass on the image normalised by its
  whole mean without a mask; the pass on the masked input with one). Cases named
  C_mirror are `Nets.predict(..., mirror=True)` on case C's input.

    ... parity_data.py --default-weights PATH

writes only the weights of a default `NetsConfig()` (random, seed 0) to PATH, for timing.

    ... parity_data.py --shipped CARD_DATA OUT

writes OUT (tests/data/nets/shipped_parity.safetensors) with the same cases for the
built-in nets (data/nets/weights.safetensors, what `matedit.nets.load()` loads): samples 0-3 of the committed test set CARD_DATA
(python/tests/data/nets_card) with their masks, and sample 4 without.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
from safetensors.numpy import save_file

from matedit.nets.model import Nets, NetsConfig, prepare, save


def image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A smooth HDR image with a few highlights and some slightly negative pixels."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    base = 0.3 + 0.2 * np.sin(6 * x + 3 * y)[..., None] * rng.uniform(0.5, 1.5, 3)
    img = base + 0.1 * rng.standard_normal((h, w, 3))
    for _ in range(3):
        img[rng.integers(h), rng.integers(w)] += rng.uniform(5, 40)
    return img.astype(np.float32)


def disc(h: int, w: int) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    return (x - w / 2 + 0.5) ** 2 + (y - h / 2 + 0.5) ** 2 < (min(h, w) / 2.5) ** 2


def predictions(nets, cases: dict) -> dict:
    data = {}
    for name, (img, mask) in cases.items():
        mirror = name.endswith("_mirror")
        pred = nets.predict(img, mask, mirror)
        with torch.no_grad():
            t = torch.from_numpy(img)[None]
            if mask is None:
                logits = nets.mask_and_normals(prepare(t), mirror)[1][0]
            else:
                m = torch.from_numpy(mask)[None]
                logits = nets(prepare(t, m), m, mirror)["mask_logits"][0]
        data[f"{name}.image"] = img
        if mask is not None:
            data[f"{name}.mask_in"] = mask.astype(np.uint8)
        data[f"{name}.normals"] = pred["normals"].astype(np.float32)
        data[f"{name}.mask"] = pred["mask"].astype(np.uint8)
        data[f"{name}.mask_prob"] = torch.sigmoid(logits).numpy().astype(np.float32)
        data[f"{name}.env"] = pred["env"].astype(np.float32)
        data[f"{name}.ctrl"] = pred["ctrl"].astype(np.float64)
        fg = pred["mask"].mean()
        print(f"{name}: {img.shape[0]}x{img.shape[1]}, mask {fg:.2f} of the pixels, min |logit| {logits.abs().min():.2e}")
    return data


def main() -> None:
    if len(sys.argv) == 4 and sys.argv[1] == "--shipped":
        from matedit.nets import load
        from matedit.nets.data import samples

        nets = load(Path(__file__).parents[3] / "data/nets/weights.safetensors").eval()
        cases = {}
        for i, smp in zip(range(5), samples(sys.argv[2])):
            img = smp["image"].numpy().astype(np.float32)
            cases[f"sample{i}"] = (img, smp["mask"].numpy() if i < 4 else None)
        data = predictions(nets, cases)
        save_file({k: np.ascontiguousarray(v) for k, v in data.items()}, sys.argv[3])
        print(f"wrote {sys.argv[3]} ({Path(sys.argv[3]).stat().st_size} bytes)")
        return
    if len(sys.argv) == 3 and sys.argv[1] == "--default-weights":
        torch.manual_seed(0)
        save(Nets(NetsConfig()), sys.argv[2])
        return
    out = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parents[3] / "tests/data/nets")
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(0)
    nets = Nets(NetsConfig(width=8, levels=2, env_height=8, env_width=16)).eval()
    with torch.no_grad():
        # the head's random bias would put most pixels on one side of 0; not exactly 0, which
        # is the logit where every feature of a pixel is 0 after the ReLUs
        nets.normals.head.bias[3] = 0.01
    save(nets, out / "weights.safetensors")

    rng = np.random.default_rng(0)
    cases = {
        "masked": (image(rng, 16, 16), disc(16, 16)),
        "unmasked": (image(rng, 12, 20), None),
        "square": (image(rng, 16, 16), None),
        "wide_masked": (image(rng, 12, 20), disc(12, 20)),
        # a black object (s = 1); not an all-black image: with every input 0, group norm
        # divides rounding noise by sqrt(eps), and PyTorch and the Rust nets round differently
        "black": (image(rng, 8, 10) * ~disc(8, 10)[..., None], disc(8, 10)),
    }
    cases["unmasked_mirror"] = cases["unmasked"]
    cases["wide_masked_mirror"] = cases["wide_masked"]
    data = predictions(nets, cases)
    save_file({k: np.ascontiguousarray(v) for k, v in data.items()}, str(out / "parity.safetensors"))
    size = sum(p.stat().st_size for p in out.glob("*.safetensors"))
    print(f"wrote {out} ({size} bytes)")


if __name__ == "__main__":
    main()
