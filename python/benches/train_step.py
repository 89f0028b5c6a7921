"""Times the PyTorch operator: its overhead over the Rust call, and a training step
(forward + backward) against the eager PyTorch peer on the same inputs, in one run.

    python3 python/benches/train_step.py [--size 128] [--env 64x128] [--peers ../shared/peers]

Overhead: the wall time of a call minus the time the Rust layer itself reports
(Renderer.last_seconds), median over --reps calls. Training step: seconds of
image = render(n, e, c); (image * g).sum().backward() with all three inputs requiring
grad, median over --reps (the peer over --peer-reps), both with --threads threads.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

import matedit
import matedit.torch as mt


def median_time(f, reps):
    f()
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), ts


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--env", default="64x128")
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--peer-reps", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--peers", default=str(Path(__file__).resolve().parents[2] / ".." / "shared" / "peers"))
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    os.environ.setdefault("RAYON_NUM_THREADS", str(args.threads))
    hl, wl = (int(x) for x in args.env.split("x"))
    rng = np.random.default_rng(0)
    n_np = matedit.sphere(args.size)
    e_np = matedit.sky(hl, wl)
    c_np = matedit.preset("gold-metallic-paint").astype(np.float32)
    g_np = rng.random((args.size, args.size, 3)).astype(np.float32)
    n, e, c, g = (torch.from_numpy(a) for a in (n_np, e_np, c_np, g_np))
    r = matedit.default_renderer(args.device)
    print(f"matedit on {r.describe()}; {args.size}x{args.size} sphere, {hl}x{wl} map, {args.threads} threads")

    # overhead of the op over the Rust call
    def over(f):
        walls, inner = [], []
        f()
        for _ in range(args.reps):
            t0 = time.perf_counter()
            f()
            walls.append(time.perf_counter() - t0)
            inner.append(r.last_seconds)
        d = [w - i for w, i in zip(walls, inner)]
        return statistics.median(d), statistics.median(inner)

    with torch.no_grad():
        ov_fwd, rust_fwd = over(lambda: mt.render(n, e, c, device=args.device))
    ov_np, _ = over(lambda: matedit.render(n_np, e_np, c_np, device=args.device))
    up = torch.from_numpy(g_np)
    ov_bwd, rust_bwd = over(
        lambda: torch.ops.matedit.render_backward(n, e, c, up, 0.0, "equirect", args.device)
    )
    print(f"forward:  Rust {rust_fwd * 1e3:8.2f} ms; overhead of matedit.torch.render {ov_fwd * 1e3:.3f} ms, of matedit.render {ov_np * 1e3:.3f} ms")
    print(f"backward: Rust {rust_bwd * 1e3:8.2f} ms; overhead of the backward op {ov_bwd * 1e3:.3f} ms")

    # training step
    def ours():
        nn, ee, cc = (t.clone().requires_grad_() for t in (n, e, c))
        (mt.render(nn, ee, cc, device=args.device) * g).sum().backward()
        return nn.grad, ee.grad, cc.grad

    t_ours, _ = median_time(ours, args.reps)
    print(f"training step, matedit.torch: {t_ours * 1e3:.1f} ms")
    peer_dir = Path(args.peers) / "torch_layer"
    if not (peer_dir / "layer.py").exists():
        print(f"no peer at {peer_dir}; pass --peers")
        return 0
    sys.path.insert(0, str(peer_dir))
    from layer import RenderingLayer  # the peer, read in place

    layer = RenderingLayer(hl, wl)

    def peer():
        nn, ee, cc = (t.clone().requires_grad_() for t in (n, e, c))
        (layer(nn, ee, cc) * g).sum().backward()
        return nn.grad, ee.grad, cc.grad

    t_peer, _ = median_time(peer, args.peer_reps)
    with torch.no_grad():
        a, b = mt.render(n, e, c, device=args.device), layer(n, e, c)
    rel = float((a - b).abs().max() / b.abs().max())
    print(f"training step, eager PyTorch peer: {t_peer * 1e3:.1f} ms (images agree to {rel:.1e} of the peak)")
    print(f"ratio peer / matedit: {t_peer / t_ours:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
