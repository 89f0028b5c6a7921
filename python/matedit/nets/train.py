"""Training the three nets on a `matedit synth` dataset.

    python -m matedit.nets.train CONFIG.py [--out DIR] [--resume] [--stop-at STEP]
    torchrun --nproc_per_node 2 -m matedit.nets.train CONFIG.py      # DDP, gloo backend

CONFIG is a small Python file setting any of DEFAULTS (below); `data` and `init` are
relative to it. `init` starts the nets from a weights file (a finished run's, to train it
further on another schedule) instead of at random; the config's model sizes must match it.
DIR (default runs/CONFIG-NAME) receives ckpt.pt (model, optimiser, step, RNG states, loss
history; written atomically every `checkpoint_every` steps or `checkpoint_seconds`),
weights.safetensors (for `matedit.nets.load`), losses.png, and run.json (config, seed, the
data's spec digest, wall time, machine). `--resume` continues from ckpt.pt to the same
weights an uninterrupted run reaches: the data stream restarts at the checkpoint's step
(data.ChunkStream), the schedule is a function of the step, and the run is deterministic
for a seed. `--stop-at STEP` ends the run after STEP steps with a checkpoint, as a job
with a time limit would.

Losses (each a mean over the object's pixels unless said otherwise; images are compared as
slog = sign log(1 + |x|) of the normalised image, see model.py):
- normals: the angle between predicted and true normals (radians);
- mask: binary cross-entropy of the foreground logits over all pixels;
- material: the predicted and true materials rendered on a sphere under three fixed probe
  lights (model.spheres), L1;
- light: L1 between log(L' + 1e-3) and log(L / s + 1e-3), L / s the light in the image's
  normalised units;
- with `render_loss`: I' = R(n', m', L') against the image I / s, and O' = R(n', m_t, L')
  against O = R(n, m_t, L / s) with m_t the material of the next sample in the batch, L1;
  R is the configured `layer` (both orthographic), over the whole mask or over
  `render_pixels` pixels of it drawn at random (the layer renders each pixel on its own,
  so a drawn pixel's value is that of the whole image's render).
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import pathlib
import platform
import random
import runpy
import sys
import time
from dataclasses import replace

import numpy as np
import torch
import torch.distributed as dist
import torch.nn.functional as F

import matedit.torch
from matedit.nets.data import ChunkStream, Mixed, Resident, spec_digest
from matedit.nets.model import Nets, NetsConfig, check_sizes, load, normalise, prepare, probe_scene, save, slog, spheres

DEFAULTS = {
    "data": "ds",  # the training folder of `matedit synth`; resident: a list mixes folders in equal shares
    "init": "",  # weights.safetensors to start from (empty: a random start)
    "width": 16,  # model sizes (model.NetsConfig)
    "levels": 3,
    "env_height": 16,
    "env_width": 32,
    "basis": [],  # the MERL presets the material net mixes (names); empty: all 90
    "frame": "square",  # how the data frames whole photos (model.NetsConfig): "square" or "photo"
    "steps": 1000,
    "batch_size": 8,  # per process
    "lr": 1e-3,
    "warmup": 50,  # steps of linear warm-up, then cosine decay to lr / 10
    "weight_decay": 1e-4,
    "w_normals": 1.0,
    "w_mask": 1.0,
    "w_material": 1.0,
    "w_light": 1.0,
    "render_loss": False,
    "w_render": 1.0,  # I' against I
    "w_edit": 1.0,  # O' against O
    "render_pixels": 0,  # the rendering losses on this many pixels of each sample's mask, drawn anew each step (0: all)
    "seed": 0,
    "threads": 2,  # torch.set_num_threads, and the layer's RAYON_NUM_THREADS unless set
    "workers": 0,  # DataLoader workers
    "shuffle_buffer": 64,
    "device": "cpu",  # the nets' torch device ("cuda" for a GPU)
    "render_device": "cpu",  # the rendering layer's device ("cpu" is bit-reproducible)
    "resident": False,  # hold the whole dataset on `device` (data.Resident) instead of streaming it
    "follow": 0,  # resident: every `follow` steps, load the chunks a running synth has finished
    "amp": "",  # "bf16": the nets' forward in bfloat16 autocast (the losses stay float32)
    "layer": "rust",  # the material loss's sphere renders: "rust" (matedit.torch) or "torch" (nets.layer)
    "log_every": 10,
    "checkpoint_every": 200,
    "checkpoint_seconds": 600.0,
}
PARTS = ("normals", "mask", "material", "light", "render", "edit")


def load_config(path) -> dict:
    """DEFAULTS updated by the settings of the Python file `path`; `data` made absolute."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such config file")
    # the config's folder on the import path while it runs, as `python CONFIG` has it, so
    # that a folder's configs can share settings from a module beside them; what it
    # imported from there is forgotten, so another folder's module of the same name loads
    folder, before = str(path.parent.resolve()), set(sys.modules)
    sys.path.insert(0, folder)
    try:
        given = runpy.run_path(str(path))
    except Exception as e:
        raise ValueError(f"{path}: {type(e).__name__}: {e}") from None
    finally:
        sys.path.remove(folder)
        for name in set(sys.modules) - before:
            if str(pathlib.Path(getattr(sys.modules[name], "__file__", None) or "/").parent) == folder:
                del sys.modules[name]
    # the file's settings: its public names but for imported modules and functions
    given = {k: v for k, v in given.items() if not k.startswith("_") and not callable(v) and not hasattr(v, "__file__")}
    cfg = dict(DEFAULTS)
    for k, v in given.items():
        if k not in DEFAULTS:
            raise ValueError(f"{path}: unknown setting {k!r}; known: {', '.join(DEFAULTS)}")
        want = type(DEFAULTS[k])
        if k == "data" and isinstance(v, list) and v and all(isinstance(f, str) for f in v):
            want = list
        if want is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if type(v) is not want:
            raise ValueError(f"{path}: {k} = {v!r}: expected a {want.__name__}")
        cfg[k] = v
    for k in ("width", "levels", "env_height", "env_width", "steps", "batch_size", "threads"):
        if cfg[k] < 1:
            raise ValueError(f"{path}: {k} = {cfg[k]}: expected at least 1")
    for k, allowed in (("amp", ("", "bf16")), ("layer", ("rust", "torch"))):
        if cfg[k] not in allowed:
            raise ValueError(f"{path}: {k} = {cfg[k]!r}: expected one of {', '.join(map(repr, allowed))}")
    if cfg["render_pixels"] < 0:
        raise ValueError(f"{path}: render_pixels = {cfg['render_pixels']}: expected 0 (all) or more")
    if cfg["follow"] and not cfg["resident"]:
        raise ValueError(f"{path}: follow = {cfg['follow']} needs resident = True")
    if not (cfg["lr"] > 0 and math.isfinite(cfg["lr"])):
        raise ValueError(f"{path}: lr = {cfg['lr']}: expected a positive number")
    if isinstance(cfg["data"], list) and not cfg["resident"]:
        raise ValueError(f"{path}: data = {cfg['data']!r}: a list of folders needs resident = True")
    folders = [cfg["data"]] if isinstance(cfg["data"], str) else cfg["data"]
    folders = [str((path.parent / f).resolve()) for f in folders]
    cfg["data"] = folders[0] if isinstance(cfg["data"], str) else folders
    if cfg["init"]:
        cfg["init"] = str((path.parent / cfg["init"]).resolve())
    return cfg


def lr_at(cfg: dict, step: int) -> float:
    if step < cfg["warmup"]:
        return cfg["lr"] * (step + 1) / cfg["warmup"]
    t = (step - cfg["warmup"]) / max(1, cfg["steps"] - cfg["warmup"])
    return cfg["lr"] * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * min(1.0, t))))


def masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of x (B, H, W[, C]) over the pixels of mask (B, H, W)."""
    m = mask.to(x.dtype)
    if x.dim() == 4:
        m = m[..., None].expand_as(x)
    return (x * m).sum() / m.sum().clamp_min(1)


def log_l1(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    return masked_mean((slog(a) - slog(b)).abs(), mask)


def angle(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The angle between unit vectors (..., 3), radians; clamped so that its gradient stays finite."""
    return torch.acos((a * b).sum(-1).clamp(-1 + 1e-6, 1 - 1e-6))


def sphere_renderer(cfg: dict, device: torch.device):
    """ctrl (B, 108) -> the probe spheres (B, P, 32, 32, 3) by the configured layer."""
    probe = tuple(t.to(device) for t in probe_scene(32, cfg["env_height"], cfg["env_width"]))
    if cfg["layer"] == "torch":
        from matedit.nets.layer import Scene

        return Scene(*probe).render_all
    return lambda ctrl: spheres(ctrl, probe, cfg["render_device"])


def losses(nets, batch: dict, cfg: dict, render_spheres) -> dict:
    """The loss parts of one batch (see the module's docstring)."""
    image, mask, dev = batch["image"], batch["mask"], cfg["render_device"]
    target, s = normalise(image, mask)
    env_t = batch["env"] / s[:, None, None, None]
    with torch.autocast(image.device.type, dtype=torch.bfloat16, enabled=cfg["amp"] == "bf16"):
        out = nets(prepare(image, mask), mask)
    out = {k: v.float() for k, v in out.items()}
    n = out["normals"]
    with torch.no_grad():
        sph_true = render_spheres(batch["ctrl"])
    parts = {
        "normals": masked_mean(angle(n, batch["normals"]), mask),
        "mask": F.binary_cross_entropy_with_logits(out["mask_logits"], mask.float()),
        "material": (slog(render_spheres(out["ctrl"])) - slog(sph_true)).abs().mean(),
        "light": (torch.log(out["env"] + 1e-3) - torch.log(env_t + 1e-3)).abs().mean(),
    }
    if cfg["render_loss"]:
        if cfg["layer"] == "torch":
            from matedit.nets.layer import render
        else:
            def render(normals, env, ctrl):
                return matedit.torch.render(normals, env, ctrl, device=dev)
        n_true = batch["normals"]
        if cfg["render_pixels"]:
            # K pixels of each mask (with replacement) as a (B, 1, K) image; a mask without
            # pixels draws anywhere and counts for nothing
            pick = torch.multinomial(mask.flatten(1).float() + 1e-12, cfg["render_pixels"], replacement=True)
            rows = torch.arange(len(pick), device=pick.device)[:, None]
            n, n_true, target, mask = (x.flatten(1, 2)[rows, pick][:, None] for x in (n, n_true, target, mask))
        n_seen = n * mask[..., None]
        parts["render"] = log_l1(render(n_seen, out["env"], out["ctrl"]), target, mask)
        m_t = batch["ctrl"].roll(1, 0)
        with torch.no_grad():
            o = render(n_true * mask[..., None], env_t, m_t)
        parts["edit"] = log_l1(render(n_seen, out["env"], m_t), o, mask)
    return parts


def plot(history: list[dict], path: pathlib.Path) -> None:
    """Loss curves as a PNG drawn with PIL: each part and the total against the step, log
    scale, as running means over 1/50 of the run (at least 1 step)."""
    from PIL import Image, ImageDraw

    w, h, left, top, right, bottom = 720, 400, 60, 40, 20, 40
    img = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(img)
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#000000"]
    keys = [k for k in (*PARTS, "total") if any(k in r for r in history)]
    win = max(1, len(history) // 50)
    curves = {}
    for k in keys:
        steps = [r["step"] for r in history if r.get(k, 0) > 0]
        vals = [r[k] for r in history if r.get(k, 0) > 0]
        smooth = [sum(vals[max(0, i - win + 1) : i + 1]) / len(vals[max(0, i - win + 1) : i + 1]) for i in range(len(vals))]
        curves[k] = list(zip(steps, smooth))
    vals = [v for c in curves.values() for _, v in c]
    if not vals:
        return
    lo, hi = math.floor(math.log10(min(vals))), math.ceil(math.log10(max(vals)))
    hi = max(hi, lo + 1)
    last = max(1, history[-1]["step"])

    def xy(step, v):
        x = left + (w - left - right) * step / last
        return x, h - bottom - (h - top - bottom) * (math.log10(v) - lo) / (hi - lo)

    d.rectangle([left, top, w - right, h - bottom], outline="black")
    for e in range(lo, hi + 1):
        y = xy(0, 10.0**e)[1]
        d.line([(left - 4, y), (left, y)], fill="black")
        d.text((4, y - 6), f"1e{e}", fill="black")
    for i, k in enumerate(keys):
        colour = colours[i % len(colours)]
        if len(curves[k]) > 1:
            d.line([xy(s, v) for s, v in curves[k]], fill=colour, width=2 if k == "total" else 1)
        d.text((left + 90 * i, 12), k, fill=colour)
    d.text((left, h - bottom + 10), f"step 0 .. {last}; running mean over {win} step(s)", fill="black")
    img.save(path)


def write_atomic(obj, path: pathlib.Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as f:
        torch.save(obj, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def train(cfg: dict, out, resume: bool = False, stop_at: int | None = None, quiet: bool = False,
          stop_after: float | None = None) -> dict:
    """Trains (or resumes) a run into folder `out`; returns {"step", "history", "seconds"}.
    `stop_at` ends it after that step, `stop_after` after that many seconds of training
    (both with a checkpoint)."""
    out = pathlib.Path(out)
    world, rank = int(os.environ.get("WORLD_SIZE", 1)), int(os.environ.get("RANK", 0))
    if world > 1 and not dist.is_initialized():
        dist.init_process_group("gloo")
    torch.set_num_threads(cfg["threads"])
    # the rendering layer's CPU threads (a rayon pool, made on its first use in the process)
    os.environ.setdefault("RAYON_NUM_THREADS", str(cfg["threads"]))
    dev = torch.device(cfg["device"])
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise ValueError(f"device {cfg['device']!r}: this torch sees no CUDA GPU")
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    # CUDA has no deterministic backward for some pooling ops: warn there rather than fail
    torch.use_deterministic_algorithms(True, warn_only=dev.type != "cpu")
    torch.manual_seed(cfg["seed"])
    np.random.seed(cfg["seed"])
    random.seed(cfg["seed"])

    sizes = ("width", "levels", "env_height", "env_width", "basis")
    nets = Nets(NetsConfig(**{k: cfg[k] for k in sizes + ("frame",)}))
    if cfg["init"] and not resume:
        start = load(cfg["init"])  # its sizes are the config's; what it saw may differ
        if replace(start.cfg, image_size=nets.cfg.image_size, frame=nets.cfg.frame) != nets.cfg:
            raise ValueError(f"{cfg['init']}: its nets are {start.cfg}, the config asks for {nets.cfg}")
        nets.load_state_dict(start.state_dict())
    opt = torch.optim.AdamW(nets.parameters(), lr=cfg["lr"], weight_decay=cfg["weight_decay"])
    step, history, seconds = 0, [], 0.0
    ckpt_path = out / "ckpt.pt"
    if resume:
        if not ckpt_path.is_file():
            raise ValueError(f"{ckpt_path}: no checkpoint to resume from")
        ck = torch.load(ckpt_path, weights_only=False, map_location="cpu")
        if {**DEFAULTS, **ck["config"]} != cfg:  # settings added since take their defaults
            changed = sorted(k for k in cfg if {**DEFAULTS, **ck["config"]}.get(k) != cfg[k])
            raise ValueError(f"{ckpt_path}: the config changed since the checkpoint ({', '.join(changed)})")
        nets.load_state_dict(ck["model"])
        step, history, seconds = ck["step"], ck["history"], ck["seconds"]
        torch.set_rng_state(ck["rng"]["torch"])
        np.random.set_state(ck["rng"]["numpy"])
        random.setstate(ck["rng"]["python"])
    nets.to(dev)
    if resume:  # the optimiser's moments follow the parameters to the device
        opt.load_state_dict(ck["optimizer"])
    model = nets
    if world > 1:
        # the buffers (the presets, the mean-light sums) are equal at the start and kept so by
        # an all-reduce: no per-step broadcast (newer torch calls the option forward_sync_buffers)
        ddp = torch.nn.parallel.DistributedDataParallel
        new = "forward_sync_buffers" in inspect.signature(ddp).parameters
        model = ddp(nets, **{"forward_sync_buffers" if new else "broadcast_buffers": False})
    if rank == 0:
        out.mkdir(parents=True, exist_ok=True)

    if cfg["resident"]:
        if world > 1:
            raise ValueError("resident = True runs in one process (no DDP)")
        data = Resident(cfg["data"], dev) if isinstance(cfg["data"], str) else Mixed(cfg["data"], dev)
        draws = torch.Generator().manual_seed(cfg["seed"])
        if resume and "draws" in ck:
            draws.set_state(ck["draws"])

        def next_batch():
            if cfg["follow"] and step % cfg["follow"] == 0:
                data.refresh()
            return data.batch(cfg["batch_size"], draws)
    else:
        stream = ChunkStream(cfg["data"], cfg["batch_size"], cfg["seed"], rank, world, cfg["shuffle_buffer"], step)
        loader = torch.utils.data.DataLoader(stream, batch_size=None, num_workers=cfg["workers"], pin_memory=dev.type == "cuda")
        batches = iter(loader)

        def next_batch():
            return {k: v.to(dev, non_blocking=True) for k, v in next(batches).items()}

    render_spheres = sphere_renderer(cfg, dev)
    weights = {p: cfg[f"w_{p}"] for p in PARTS}
    end = cfg["steps"] if stop_at is None else min(stop_at, cfg["steps"])

    def checkpoint() -> None:
        if rank != 0:
            return
        rng = {"torch": torch.get_rng_state(), "numpy": np.random.get_state(), "python": random.getstate()}
        state = {"model": nets.state_dict(), "optimizer": opt.state_dict(), "step": step, "history": history}
        if cfg["resident"]:
            state.update(draws=draws.get_state(), samples=len(data))
        write_atomic({**state, "rng": rng, "seconds": seconds, "config": cfg}, ckpt_path)
        save(nets, out / ".weights.safetensors", {"step": step, "data_spec": spec_digest(cfg["data"])})
        os.replace(out / ".weights.safetensors", out / "weights.safetensors")
        plot(history, out / "losses.png")
        run = {
            "config": cfg,
            "seed": cfg["seed"],
            "data_spec_sha256": spec_digest(cfg["data"]),
            "step": step,
            "wall_seconds": round(seconds, 3),
            "world_size": world,
            "ranks_agree": agree,
            "machine": {"node": platform.node(), "cpu": platform.processor() or platform.machine(),
                        "cpus": os.cpu_count(), "python": platform.python_version(), "torch": torch.__version__},
        }
        (out / "run.json").write_text(json.dumps(run, indent=1))

    def ranks_agree() -> bool:
        """Whether every rank holds the same weights (DDP keeps them so; checked, not hoped)."""
        if world == 1:
            return True
        sums = torch.stack([p.detach().double().sum() for p in nets.parameters()])
        lo, hi = sums.clone(), sums.clone()
        dist.all_reduce(lo, dist.ReduceOp.MIN)
        dist.all_reduce(hi, dist.ReduceOp.MAX)
        return torch.equal(lo, hi)

    agree = True
    last_ckpt = time.time()
    t_log, tick, seconds0 = time.time(), time.time(), seconds
    # the steps' losses stay on the device until read, every step when streaming, every
    # log_every steps when resident (reading one waits for the GPU)
    pending, read_every = [], cfg["log_every"] if cfg["resident"] else 1

    def read_losses() -> None:
        vals = torch.stack([torch.stack(list(p.values())) for _, p in pending]).tolist()
        for (at, p), row in zip(pending, vals):
            rec = dict(zip(p, row))
            if not math.isfinite(rec["total"]):
                detail = ", ".join(f"{k} {v:.3g}" for k, v in rec.items() if k != "total")
                raise ValueError(f"step {at}: the loss is {rec['total']} ({detail})")
            history.append({"step": at + 1, **rec})
        pending.clear()

    while step < end and not (stop_after and seconds - seconds0 >= stop_after):
        batch = next_batch()
        check_sizes(nets.cfg, batch["image"], batch["env"], str(cfg["data"]))
        nets.cfg.image_size = batch["image"].shape[1]
        for g in opt.param_groups:
            g["lr"] = lr_at(cfg, step)
        parts = losses(model, batch, cfg, render_spheres)
        total = sum(weights[k] * v for k, v in parts.items())
        pending.append((step, {"total": total.detach(), **{k: v.detach() for k, v in parts.items()}}))
        if len(pending) >= read_every:
            read_losses()
        opt.zero_grad(set_to_none=True)
        total.backward()
        opt.step()
        with torch.no_grad():  # the mean-light baseline: every rank adds every rank's lights
            _, s = normalise(batch["image"], batch["mask"])
            stats = torch.cat([torch.log(batch["env"] / s[:, None, None, None] + 1e-3).double().sum(0).flatten(),
                               torch.full((1,), float(len(s)), dtype=torch.float64, device=dev)])
            if world > 1:
                dist.all_reduce(stats)
            nets.log_light_sum += stats[:-1].view_as(nets.log_light_sum)
            nets.light_count += stats[-1]
        step += 1
        if step % cfg["log_every"] == 0 or step == end:
            if pending:
                read_losses()
            now = time.time()
            if rank == 0 and not quiet:
                ms = 1000 * (now - t_log) / (step % cfg["log_every"] or cfg["log_every"])
                detail = " ".join(f"{k} {v:.4f}" for k, v in history[-1].items() if k not in ("step", "total"))
                lr = lr_at(cfg, step - 1)
                more = f" {len(data)} samples" if cfg["resident"] else ""
                print(f"step {step}/{cfg['steps']} loss {history[-1]['total']:.4f} ({detail}) lr {lr:.2e} {ms:.0f} ms/step{more}", flush=True)
                t_log = now
        now = time.time()
        seconds += now - tick
        tick = now
        if step % cfg["checkpoint_every"] == 0 or now - last_ckpt > cfg["checkpoint_seconds"]:
            if pending:
                read_losses()
            checkpoint()
            last_ckpt = time.time()
    if pending:
        read_losses()
    agree = ranks_agree()
    checkpoint()
    if world > 1:
        dist.barrier()  # no rank leaves (and tears down gloo) while rank 0 still writes
    return {"step": step, "history": history, "seconds": seconds}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m matedit.nets.train", description=__doc__.split("\n")[0])
    ap.add_argument("config", help="a Python file of settings (see DEFAULTS)")
    ap.add_argument("--out", help="run folder (default runs/CONFIG-NAME)")
    ap.add_argument("--resume", action="store_true", help="continue from OUT/ckpt.pt")
    ap.add_argument("--stop-at", type=int, help="stop after this many steps, with a checkpoint")
    ap.add_argument("--stop-after", type=float, help="stop after this many seconds of training, with a checkpoint")
    args = ap.parse_args(argv)
    try:
        cfg = load_config(args.config)
        out = args.out or os.path.join("runs", pathlib.Path(args.config).stem)
        res = train(cfg, out, resume=args.resume, stop_at=args.stop_at, stop_after=args.stop_after)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if int(os.environ.get("RANK", 0)) == 0:
        print(f"{res['step']} steps in {res['seconds']:.1f} s; weights in {pathlib.Path(out) / 'weights.safetensors'}")
    return 0


if __name__ == "__main__":
    code = main()
    if dist.is_initialized():
        # Tearing down gloo (destroy_process_group, or the interpreter's exit) aborted a rank
        # with "terminate called without an active exception" in 3 of 45 two-process runs,
        # after its work was done; none in 30 leaving at once. Every file is written and
        # closed, and (after training) the ranks have passed a barrier: a DDP rank skips it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)
