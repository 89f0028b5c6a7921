"""Samples per second of a training batch through the layer, forward + backward to all
three inputs, against the Dr.Jit peer running the same scenes one by one, in one run.

    python3 python/benches/train_batch.py [--batch 32] [--size 64] [--env 32x64] [--reps 5]
        [--threads 2] [--peers ../shared/peers] [--out FILE.json]

The batch: `--batch` scenes of `--size` x `--size` normals, spheres and bumpy surfaces in
turn (`matedit.sphere`, `matedit.bumpy` with the scene's seed), each with its own nine-lobe
material (`matedit.random_material(100 + i)`: every lobe its own scale and exponent curve)
and its own map (the built-in sky at `--env`, turned by a seeded number of columns and
tinted per channel), orthographic, `equirect`; upstream gradient uniform in [-1, 1].

Timed (median of `--reps` after a warm-up, `--threads` threads everywhere):
- `renderer`: `Renderer.render` + `Renderer.backward` on the whole batch (NumPy in and out);
- `torch`: `matedit.torch.render` on (B, ...) tensors requiring grad, then
  `(image * g).sum().backward()`;
- `drjit`: the peer (`DrJitLayer.forward_backward`) on the same scenes one by one, in its own
  process; its images are checked against ours.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

import matedit
import matedit.torch as mt

sys.path.insert(0, str(Path(__file__).resolve().parent))
from train_step import median_time  # noqa: E402  (beside this file)

PEER = r"""
import os, sys, time, json
import numpy as np
d = np.load(sys.argv[1]); reps = int(sys.argv[2]); threads = int(sys.argv[4])
os.environ.setdefault("DRJIT_CACHE_DIR", "/tmp/peers_time_drjit_cache")
sys.path.insert(0, os.path.join(sys.argv[3], "drjit_layer"))
import drjit as dr
dr.set_thread_count(threads)
from layer import DrJitLayer
N, E, C, G = d["normals"], d["env"], d["ctrl"].astype(np.float32), d["upstream"]
L = DrJitLayer(E.shape[1], E.shape[2])
def batch():
    return [L.forward_backward(N[i], E[i], C[i], G[i]) for i in range(len(N))]
batch()
ts = []
for _ in range(reps):
    t = time.perf_counter(); batch(); ts.append(time.perf_counter() - t)
images = np.stack([np.asarray(L.forward(N[i], E[i], C[i])) for i in range(len(N))])
np.save(sys.argv[1] + ".images.npy", images)
print(json.dumps({"fb": sorted(ts)[len(ts) // 2]}))
"""


def batch_inputs(b: int, size: int, hl: int, wl: int):
    rng = np.random.default_rng(0)
    sky = matedit.sky(hl, wl)
    normals = np.stack(
        [matedit.sphere(size) if i % 2 == 0 else matedit.bumpy(size, size, i) for i in range(b)]
    )
    env = np.stack(
        [
            np.roll(sky, int(rng.integers(wl)), axis=1) * rng.uniform(0.5, 1.5, 3).astype(np.float32)
            for _ in range(b)
        ]
    ).astype(np.float32)
    ctrl = np.stack([matedit.random_material(100 + i) for i in range(b)])
    upstream = rng.uniform(-1, 1, normals.shape).astype(np.float32)
    return normals, env, ctrl, upstream


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--env", default="32x64")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--peers", default=str(Path(__file__).resolve().parents[2] / ".." / "shared" / "peers"))
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    os.environ.setdefault("RAYON_NUM_THREADS", str(args.threads))
    hl, wl = (int(x) for x in args.env.split("x"))
    n, e, c, g = batch_inputs(args.batch, args.size, hl, wl)
    r = matedit.Renderer("cpu")
    print(
        f"{args.batch} scenes of {args.size}x{args.size}, maps {hl}x{wl}, nine-lobe random "
        f"materials; matedit on {r.describe()}; {args.threads} threads"
    )
    results = {}

    def renderer():
        r.render(n, e, c)
        return r.backward(n, e, c, g)

    results["renderer"] = median_time(renderer, args.reps)[0]
    tn, te, tc, tg = (torch.from_numpy(a) for a in (n, e, c.astype(np.float32), g))

    def step():
        nn, ee, cc = (t.clone().requires_grad_() for t in (tn, te, tc))
        (mt.render(nn, ee, cc, device="cpu") * tg).sum().backward()
        return nn.grad, ee.grad, cc.grad

    results["torch"] = median_time(step, args.reps)[0]
    ours = r.render(n, e, c)
    peer_dir = Path(args.peers)
    if (peer_dir / "drjit_layer" / "layer.py").exists():
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "batch.npz")
            np.savez(path, normals=n, env=e, ctrl=c, upstream=g)
            out = subprocess.run(
                [sys.executable, "-c", PEER, path, str(args.reps), str(peer_dir), str(args.threads)],
                capture_output=True,
                text=True,
                env={**os.environ, "OMP_NUM_THREADS": "1"},
            )
            if out.returncode != 0:
                print(f"drjit peer failed: {out.stderr.strip().splitlines()[-1:]}")
            else:
                results["drjit"] = json.loads(out.stdout.strip().splitlines()[-1])["fb"]
                theirs = np.load(path + ".images.npy")
                rel = float(np.abs(theirs - ours).max() / np.abs(ours).max())
                print(f"Dr.Jit's images agree with ours to {rel:.1e} of the peak")
    else:
        print(f"no peer at {peer_dir}; pass --peers")
    for name, t in results.items():
        line = f"{name:>9}: {t:.3f} s per batch, {args.batch / t:7.1f} samples/s"
        if "drjit" in results and name != "drjit":
            line += f", {results['drjit'] / t:.2f}x Dr.Jit"
        print(line)
    if args.out:
        Path(args.out).write_text(json.dumps({"args": vars(args), "seconds": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
