"""Fit the 108 control points of a material to a rendered image with torch.optim.Adam.

The target is a sphere in one material under the built-in sky; the fit starts from
another material and optimises through matedit.torch.render. Scales are free; exponents
are exp(b) (at most 9999), so they stay non-negative whatever Adam does. The loss compares
log(1 + image), so that the highlight does not outweigh the rest of the sphere.

    python3 python/examples/fit_material.py                     # 64 x 64, 300 steps
    python3 python/examples/fit_material.py --size 32 --steps 150

It prints the loss as it goes and the PSNR of the fitted render against the target at
the end, and exits non-zero if that PSNR is below --min-psnr.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
import torch

import matedit
import matedit.torch as mt

# flat index of ctrl: ((channel * 3 + lobe) * 2 + t) * 6 + control point; t = 1: exponent
EXPONENT = np.array([((k * 3 + s) * 2 + t) * 6 + j == ((k * 3 + s) * 2 + 1) * 6 + j
                     for k in range(3) for s in range(3) for t in range(2) for j in range(6)])


MAX_EXPONENT = 9999.0


def to_params(ctrl: np.ndarray) -> torch.Tensor:
    """Unconstrained parameters: scales as they are, exponents as log(max(m1, 1e-3))."""
    p = ctrl.astype(np.float64).copy()
    p[EXPONENT] = np.log(np.maximum(p[EXPONENT], 1e-3))
    return torch.tensor(p, dtype=torch.float32, requires_grad=True)


def to_ctrl(p: torch.Tensor) -> torch.Tensor:
    mask = torch.from_numpy(EXPONENT)
    # the layer takes exponents up to 1e4; a few presets sit at that bound
    return torch.where(mask, p.exp().clamp(max=MAX_EXPONENT), p)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of a against b, with b's largest value as the peak."""
    mse = float(np.mean((a.astype(np.float64) - b) ** 2))
    return 10.0 * math.log10(float(b.max()) ** 2 / max(mse, 1e-30))


def fit(size=64, steps=300, target="gold-metallic-paint", start="red-specular-plastic",
        lr=0.05, log_every=25, device="cpu", quiet=False):
    """Returns (fitted ctrl, PSNR in dB, seconds)."""
    normals = torch.from_numpy(matedit.sphere(size))
    env = torch.from_numpy(matedit.sky(16, 32))
    truth = torch.from_numpy(matedit.preset(target)).float()
    with torch.no_grad():
        goal = mt.render(normals, env, truth, device=device)
    params = to_params(matedit.preset(start))
    opt = torch.optim.Adam([params], lr=lr)
    mask = (normals.square().sum(-1, keepdim=True) > 0).float()
    goal_log = torch.log1p(goal)
    t0 = time.perf_counter()
    for step in range(steps + 1):
        opt.zero_grad()
        image = mt.render(normals, env, to_ctrl(params), device=device)
        loss = ((torch.log1p(image) - goal_log) * mask).square().mean()
        if not quiet and (step % log_every == 0 or step == steps):
            print(f"step {step:4d}  loss {loss.item():.3e}")
        if step == steps:
            break
        loss.backward()
        opt.step()
    seconds = time.perf_counter() - t0
    with torch.no_grad():
        fitted = to_ctrl(params).double()
        image = mt.render(normals, env, fitted.float(), device=device)
    return fitted.numpy(), psnr(image.numpy(), goal.numpy()), seconds


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=64, help="sphere size in pixels")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--target", default="gold-metallic-paint", help="preset rendered as the target")
    ap.add_argument("--start", default="red-specular-plastic", help="preset the fit starts from")
    ap.add_argument("--lr", type=float, default=0.05)
    ap.add_argument("--min-psnr", type=float, default=35.0)
    args = ap.parse_args()
    ctrl, db, seconds = fit(args.size, args.steps, args.target, args.start, args.lr)
    print(f"PSNR {db:.1f} dB against the target after {args.steps} steps ({seconds:.1f} s)")
    if db < args.min_psnr:
        print(f"below --min-psnr {args.min_psnr}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
