"""Times `matedit.backward` for some of the gradients (`wanted=`) against all three, on a
128 x 128 sphere under a 64 x 128 sky, gold, an upstream gradient of ones: the median of
`--reps` calls after one warm-up call, per device.

    python3 python/benches/wanted.py [--devices cpu,gpu] [--reps 5]
"""

import argparse
import time

import numpy as np

import matedit


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--devices", default="cpu,gpu")
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args()
    normals = matedit.sphere(128)
    env = matedit.sky(64, 128)
    ctrl = matedit.preset("gold")
    up = np.ones((128, 128, 3), np.float32)
    subsets = [None, ["ctrl"], ["normals"], ["env"], ["env", "ctrl"], ["normals", "ctrl"]]
    for device in args.devices.split(","):
        try:
            r = matedit.Renderer(device)
        except RuntimeError as e:
            print(f"{device}: skipped ({e})")
            continue
        full = None
        for wanted in subsets:
            r.backward(normals, env, ctrl, up, wanted=wanted)
            times = []
            for _ in range(args.reps):
                t0 = time.perf_counter()
                r.backward(normals, env, ctrl, up, wanted=wanted)
                times.append(time.perf_counter() - t0)
            t = float(np.median(times))
            full = full or t
            name = "all" if wanted is None else "+".join(wanted)
            print(f"{device:4} {name:14} {t * 1e3:9.1f} ms  {t / full:6.0%} of all")


if __name__ == "__main__":
    main()
