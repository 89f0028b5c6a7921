"""Times model.spheres (B materials on the 32 x 32 probe sphere under 3 probe lights),
forward and forward + backward in ctrl, with the Rust layer and with nets/layer.py.

    python scripts/bench_layer.py [--batch 64] [--threads 2] [--device cpu|cuda] [--repeat 3]

Prints the best of --repeat runs per backend. The Rust layer runs on the CPU (its rayon
pool; RAYON_NUM_THREADS sets its threads); the torch layer on --device, and off the CPU its
images and ctrl gradients are compared with the torch layer's on the CPU. Where the matedit
extension is not installed, layer.py is loaded from the repository and the sphere, lights and
materials are made up (a unit sphere, random lights, random valid control points).
"""

import argparse
import importlib.util
import pathlib
import sys
import time

import torch

REPO_NETS = pathlib.Path(__file__).resolve().parents[1] / "python" / "matedit" / "nets"
try:
    import matedit
    import matedit.nets

    matedit.nets.__path__.insert(0, str(REPO_NETS))  # the repository's layer.py, not an installed copy
    from matedit.nets import layer, model
except ImportError:  # no extension: layer.py alone
    matedit = model = None
    spec = importlib.util.spec_from_file_location("layer", REPO_NETS / "layer.py")
    layer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(layer)


def made_up(batch: int):
    """A unit sphere (32, 32, 3), 3 random lights (3, 16, 32, 3), random materials (B, 108):
    scales in [0, 1], exponents in [0, 300]."""
    g = torch.Generator().manual_seed(0)
    t = (torch.arange(32) + 0.5) / 16 - 1
    x, y = t[None, :].expand(32, 32), -t[:, None].expand(32, 32)
    z2 = 1 - x * x - y * y
    n = torch.stack([x, y, z2.clamp_min(0).sqrt()], -1) * (z2 > 0)[..., None]
    envs = torch.rand(3, 16, 32, 3, generator=g) ** 4 * 4
    ctrl = torch.rand(batch, 3, 3, 2, 6, generator=g) * torch.tensor([1.0, 300.0])[:, None]
    return (n, envs), ctrl.reshape(batch, 108)


def best(fn, repeat: int, sync) -> tuple[float, float]:
    """The least (forward, forward + backward) seconds of fn() over `repeat` runs after one warm-up."""
    fn().abs().sum().backward()
    times = []
    for _ in range(repeat):
        sync()
        t0 = time.perf_counter()
        y = fn()
        sync()
        t1 = time.perf_counter()
        y.abs().sum().backward()
        sync()
        times.append((t1 - t0, time.perf_counter() - t0))
    return min(t[0] for t in times), min(t[1] for t in times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-rust", action="store_true", help="time the torch layer alone")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    dev = torch.device(a.device)
    sync = torch.cuda.synchronize if dev.type == "cuda" else (lambda: None)
    if model is None:
        probe, ctrl = made_up(a.batch)
        a.no_rust = True
    else:
        probe = model.probe_scene(32)
        merl = model.merl_presets(matedit.presets()[: model.N_MERL])
        g = torch.Generator().manual_seed(0)
        ctrl = torch.softmax(torch.randn(a.batch, model.N_MERL, generator=g) * 3, -1) @ merl
    c_cpu, c_dev = ctrl.clone().requires_grad_(), ctrl.to(dev).requires_grad_()
    t0 = time.perf_counter()
    scene = layer.Scene(*(t.to(dev) for t in probe))
    sync()
    print(f"Scene (once per probe): {time.perf_counter() - t0:.4f} s on {dev}")
    rows = [] if a.no_rust else [("rust (matedit.torch.render, cpu)", lambda: model.spheres(c_cpu, probe))]
    rows.append((f"torch (nets/layer.py, {dev})", lambda: scene.render_all(c_dev)))
    for name, fn in rows:
        fwd, both = best(fn, a.repeat, sync)
        print(f"{name}: batch {a.batch} x 3 probes: forward {fwd:.4f} s, forward + backward {both:.4f} s")
    if dev.type != "cpu":
        check(scene, probe, c_dev, ctrl)
    sys.stdout.flush()


def check(scene, probe, c_dev, ctrl) -> None:
    """Prints the max differences of images and ctrl gradients on the device vs the CPU,
    relative to their max."""
    up = torch.randn(len(ctrl), 3, 32, 32, 3, generator=torch.Generator().manual_seed(1))
    c_cpu = ctrl.clone().requires_grad_()
    c_dev.grad = None
    ref, out = layer.Scene(*probe).render_all(c_cpu), scene.render_all(c_dev)
    (ref * up).sum().backward()
    (out * up.to(out.device)).sum().backward()
    for name, a, b in [("image", out.detach().cpu(), ref.detach()), ("d ctrl", c_dev.grad.cpu(), c_cpu.grad)]:
        print(f"{name}: device vs cpu, max |diff| / max = {((a - b).abs().max() / b.abs().max()).item():.2e}")


if __name__ == "__main__":
    main()
