"""Evaluating trained nets on a held-out `matedit synth` folder, beside baselines.

    python -m matedit.nets.evaluate WEIGHTS DATA [--json OUT] [--batch-size B] [--limit N]

DATA must be a split no training choice saw (synthesise it with another seed; the folder
the weights were trained on, by its spec digest, is refused). Every
metric is over the object's pixels (the true mask), averaged over samples:
- normals: mean and median angle (degrees) to the true normals, % of pixels under 11.25,
  22.5 and 30 degrees; baseline: `balloon` normals inflated from the true mask;
- mask: IoU of the predicted mask (logit > 0) with the true one; baseline: every pixel;
- material: PSNR (dB) of the material rendered on a sphere under the three probe lights
  (model.spheres) against the true material's, peak = the true renders' maximum;
  baseline: `mean_material`, the mean of the presets the material net mixes (its basis,
  the training materials' presets);
- light: scale-invariant log RMSE, the RMS over texels and channels of d - mean(d) with
  d = log(L' + 1e-3) - log(L / s + 1e-3); baseline: `mean_light`, the training lights'
  geometric mean recorded in the weights; and the PSNR (dB) of a white Lambertian sphere
  (preset matte-white) lit by the predicted light against the same sphere lit by the true
  one (light_diffuse_psnr_db);
- I' = R(n', m', L') against I / s and O' = R(n', m_t, L') against O = R(n, m_t, L / s),
  m_t the next sample's material: PSNR (dB) over the object, peak = the target's maximum
  there; baseline: the three baselines rendered the same way. unedited_psnr_db is I / s
  itself against O (the same in both columns): O' beats leaving the photo alone by
  edit_psnr_db - unedited_psnr_db. edit_true_normals_psnr_db and edit_true_light_psnr_db:
  O' with the true normals n, or the true light L / s, in place of the guessed ones (what
  each guess costs the edit: docs/edit.md, "What each guess costs").
With `--at-nets-size` the nets see each image as `matedit edit` shows them a photo: resized
to the size they were trained at (their image_size; area averaging down, bilinear up), their
normals and mask logits brought back to the data's size bilinearly; the metrics stay at the
data's size. So nets trained at different sizes are compared on the same images.
With `--mirror` each net's answers are averaged with those for the image mirrored left to
right (`Nets.forward`), as `matedit edit` runs them.
It prints a table and writes the numbers as JSON.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys

import numpy as np
import torch
import torch.nn.functional as F

import matedit.torch
from matedit.nets.data import collate, samples, spec_digest
from matedit.nets.model import Nets, check_sizes, load, normalise, prepare, probe_scene, spheres

# ---------------------------------------------------------------------------------------
# baselines


def balloon(mask, iterations: int = 2000, tol: float = 1e-6) -> np.ndarray:
    """Normals (H, W, 3) inflated from a mask (H, W): h solves the Poisson equation
    laplace(h) = -4 inside the mask with h = 0 outside (conjugate gradients, 5-point
    stencil, pixel units), the height is z = sqrt(h), and the normal is (-dz/dx, -dz/dy, 1)
    normalised (x right, y up). For a disc of radius R, h = R^2 - r^2 and z is the
    hemisphere: the square-root profile makes silhouettes face sideways."""
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask: shape {m.shape}, expected (H, W)")
    m = m.astype(bool)
    h = np.zeros(m.shape)
    if m.any():
        inside = np.pad(m, 1)

        def apply(v):  # -laplace(v) inside the mask, v = 0 outside
            p = np.pad(v * m, 1)
            lap = p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:] - 4 * p[1:-1, 1:-1]
            return -lap * inside[1:-1, 1:-1]

        b = 4.0 * m
        r = b - apply(h)
        p, rr = r.copy(), (r * r).sum()
        for _ in range(iterations):
            ap = apply(p)
            a = rr / (p * ap).sum()
            h += a * p
            r -= a * ap
            rr_new = (r * r).sum()
            if rr_new < tol * tol * (b * b).sum():
                break
            p, rr = r + rr_new / rr * p, rr_new
    z = np.pad(np.sqrt(np.maximum(h, 0)), 1)
    dzdx = (z[1:-1, 2:] - z[1:-1, :-2]) / 2
    dzdy = (z[:-2, 1:-1] - z[2:, 1:-1]) / 2  # row 0 is the top: y grows upwards
    n = np.stack([-dzdx, -dzdy, np.ones_like(dzdx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return (n * m[..., None]).astype(np.float32)


def mean_material(nets: Nets) -> torch.Tensor:
    """The mean of the presets the material net mixes (108,): the centre of its span."""
    return nets.material.presets.mean(0)


def mean_light(nets: Nets) -> torch.Tensor:
    """The training lights' geometric mean (H_L, W_L, 3), in normalised units."""
    return nets.mean_light()


# ---------------------------------------------------------------------------------------
# metrics


def angles_deg(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The angles (degrees) between normals a and b (..., 3) at the pixels of mask."""
    cos = (torch.nn.functional.normalize(a, dim=-1) * b).sum(-1).clamp(-1, 1)
    return torch.rad2deg(torch.acos(cos))[mask]


def psnr(pred: torch.Tensor, true: torch.Tensor, mask: torch.Tensor | None = None) -> float:
    """10 log10(peak^2 / MSE) over the pixels of mask (all without), peak = max of true there."""
    if mask is not None:
        pred, true = pred[mask], true[mask]
    mse = float(((pred - true) ** 2).mean())
    peak = float(true.max())
    return 10 * math.log10(peak * peak / mse) if mse > 0 and peak > 0 else float("inf")


def si_log_rmse(pred: torch.Tensor, true: torch.Tensor) -> float:
    d = torch.log(pred + 1e-3) - torch.log(true + 1e-3)
    return float(((d - d.mean()) ** 2).mean().sqrt())


def iou(a: torch.Tensor, b: torch.Tensor) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union > 0 else 1.0


def evaluate(nets: Nets, folder, batch_size: int = 8, limit: int | None = None, device: str = "cpu",
             at_nets_size: bool = False, mirror: bool = False) -> dict:
    """The metrics of `nets` and of the baselines on the samples of `folder` (see the module's
    docstring): {"samples", "nets": {...}, "baselines": {...}}. at_nets_size: the nets see
    each image resized to their image_size; mirror: the nets' answers averaged with the
    mirrored image's (`Nets.forward`)."""
    nets.eval()
    probe = probe_scene(32, nets.cfg.env_height, nets.cfg.env_width)
    m_mean, l_mean = mean_material(nets), mean_light(nets)
    acc = {k: [] for k in ("nets", "baselines")}
    angles = {k: [] for k in acc}
    stream = itertools.islice(samples(folder), limit)
    count = 0
    while batch := list(itertools.islice(stream, batch_size)):
        count += len(batch)
        with torch.no_grad():
            size = nets.cfg.image_size if at_nets_size else None
            _eval_batch(nets, collate(batch), probe, m_mean, l_mean, device, acc, angles, str(folder), size, mirror)
    if count == 0:
        raise ValueError(f"{folder}: no samples")
    res = {"samples": count}
    for k in acc:
        a = torch.cat(angles[k])
        rows = {name: float(np.mean([r[name] for r in acc[k]])) for name in acc[k][0]}
        rows.update(
            normals_mean_deg=float(a.mean()),
            normals_median_deg=float(a.median()),
            **{f"normals_under_{t}_pct": float(100 * (a < t).float().mean()) for t in (11.25, 22.5, 30)},
        )
        res[k] = rows
    return res


def resize(x: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """(B, C, H, W) to `size`: area averaging where it shrinks, bilinear where it grows."""
    if tuple(x.shape[2:]) == size:
        return x
    if size[0] <= x.shape[2] and size[1] <= x.shape[3]:
        return F.interpolate(x, size=size, mode="area")
    return F.interpolate(x, size=size, mode="bilinear", align_corners=False)


def _eval_batch(nets, b, probe, m_mean, l_mean, device, acc, angles, where: str, size: int | None = None,
                mirror: bool = False) -> None:
    image, mask = b["image"], b["mask"]
    hw = tuple(image.shape[1:3])
    target, s = normalise(image, mask)
    env_t = b["env"] / s[:, None, None, None]
    x = prepare(image, mask)
    net_hw = hw if size is None else (size, size * hw[1] // hw[0])
    if net_hw != hw:  # the nets at their own size (mask and image resized), brought back
        m_in = resize(mask[:, None].float(), net_hw)[:, 0] > 0.5
        small = resize_image(image, net_hw)
        check_sizes(nets.cfg, small, b["env"], where)
        x = prepare(small, m_in)
        out = nets(x, m_in, mirror)
        n = resize(out["normals"].permute(0, 3, 1, 2), hw).permute(0, 2, 3, 1)
        out["normals"] = F.normalize(n, dim=-1, eps=1e-6)
        pred_mask = resize(nets.mask_and_normals(x, mirror)[1][:, None], hw)[:, 0] > 0
    else:
        check_sizes(nets.cfg, image, b["env"], where)
        out = nets(x, mask, mirror)
        pred_mask = nets.mask_and_normals(x, mirror)[1] > 0
    n_bal = torch.from_numpy(np.stack([balloon(m) for m in mask.numpy()]))
    nb = image.shape[0]
    guesses = {
        "nets": (out["normals"] * mask[..., None], out["ctrl"], out["env"]),
        "baselines": (n_bal, m_mean.expand(nb, -1).contiguous(), l_mean.expand(nb, -1, -1, -1).contiguous()),
    }
    m_t = b["ctrl"].roll(1, 0)
    o = matedit.torch.render(b["normals"], env_t, m_t, device=device)
    sph_true = spheres(b["ctrl"], probe, device)
    # the light judged by a white Lambertian sphere it lights (preset matte-white)
    white = torch.from_numpy(matedit.preset("matte-white")).float().expand(nb, -1).contiguous()
    diffuse_true = matedit.torch.render(probe[0], env_t, white, device=device)
    for kind, (n, ctrl, env) in guesses.items():
        angles[kind].append(angles_deg(n, b["normals"], mask))
        sph = spheres(ctrl, probe, device)
        i_p = matedit.torch.render(n, env, ctrl, device=device)
        o_p = matedit.torch.render(n, env, m_t, device=device)
        o_true_n = matedit.torch.render(b["normals"], env, m_t, device=device)
        o_true_l = matedit.torch.render(n, env_t, m_t, device=device)
        diffuse = matedit.torch.render(probe[0], env, white, device=device)
        for j in range(nb):
            acc[kind].append(
                {
                    "mask_iou": iou(pred_mask[j] if kind == "nets" else torch.ones_like(mask[j]), mask[j]),
                    "material_sphere_psnr_db": psnr(sph[j], sph_true[j]),
                    "light_si_log_rmse": si_log_rmse(env[j], env_t[j]),
                    "light_diffuse_psnr_db": psnr(diffuse[j], diffuse_true[j], probe[0].abs().sum(-1) > 0),
                    "render_psnr_db": psnr(i_p[j], target[j], mask[j]),
                    "edit_psnr_db": psnr(o_p[j], o[j], mask[j]),
                    "edit_true_normals_psnr_db": psnr(o_true_n[j], o[j], mask[j]),
                    "edit_true_light_psnr_db": psnr(o_true_l[j], o[j], mask[j]),
                    # the edit left undone: the image I itself against O
                    "unedited_psnr_db": psnr(target[j], o[j], mask[j]),
                }
            )


def resize_image(image: torch.Tensor, hw: tuple[int, int]) -> torch.Tensor:
    """A linear image (B, H, W, 3) resized to hw (as `resize`)."""
    return resize(image.permute(0, 3, 1, 2), hw).permute(0, 2, 3, 1)


def weights_data_spec(path) -> str | None:
    """The spec digest of the training data recorded in a weights file, if any."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            return json.loads((f.metadata() or {}).get("data_spec", "null"))
    except Exception:
        return None  # load() reports what is wrong with the file


def report(res: dict) -> str:
    lines = [f"{res['samples']} samples", f"{'metric':28} {'nets':>10} {'baseline':>10}"]
    for name in res["nets"]:
        lines.append(f"{name:28} {res['nets'][name]:10.3f} {res['baselines'][name]:10.3f}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m matedit.nets.evaluate", description=__doc__.split("\n")[0])
    ap.add_argument("weights", help="a weights.safetensors of matedit.nets.train")
    ap.add_argument("data", help="a held-out folder written by `matedit synth`")
    ap.add_argument("--json", help="where to write the metrics (default WEIGHTS.eval.json)")
    ap.add_argument("--batch-size", type=int, default=8)
    ap.add_argument("--limit", type=int, help="evaluate the first N samples only")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--at-nets-size", action="store_true", help="the nets see each image resized to their training size")
    ap.add_argument("--mirror", action="store_true", help="average the nets' answers with the mirrored image's")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    try:
        trained_on = weights_data_spec(args.weights)
        if trained_on is not None and trained_on == spec_digest(args.data):
            raise ValueError(f"{args.data}: the data these weights were trained on; evaluate on a held-out split")
        res = evaluate(load(args.weights), args.data, args.batch_size, args.limit, at_nets_size=args.at_nets_size,
                       mirror=args.mirror)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    res["weights"], res["data"], res["at_nets_size"], res["mirror"] = args.weights, args.data, args.at_nets_size, args.mirror
    path = args.json or f"{args.weights}.eval.json"
    with open(path, "w") as f:
        json.dump(res, f, indent=1)
    print(report(res))
    print(f"written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
