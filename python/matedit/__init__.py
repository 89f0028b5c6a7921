"""matedit: the rendering layer of Liu et al., "Material Editing Using a Physically Based
Rendering Network" (ICCV 2017), on NumPy arrays, with its backward pass.

    import matedit
    normals = matedit.sphere(128)                  # (128, 128, 3) float32
    env = matedit.sky(64, 128)                     # (64, 128, 3) float32, or load_env(path)
    ctrl = matedit.preset("gold-metallic-paint")   # (108,) float64
    image = matedit.render(normals, env, ctrl)     # (128, 128, 3) float32
    d_env, d_normals, d_ctrl = matedit.backward(normals, env, ctrl, upstream)

Arrays may carry a leading batch axis: normals (B, H, W, 3), env (B, H_L, W_L, 3), ctrl
(B, 108); an input given once is shared by the batch. normals, env and upstream are
float32; ctrl is float64 or float32. Invalid input raises ValueError with the library's
one-line message; a device failure raises RuntimeError.

`matedit.torch` (imported on its own: `import matedit.torch`) has the PyTorch operator.
`matedit.synth(spec, out_dir, shard=(i, n))` writes a dataset's shard like `matedit synth`;
`matedit.ray.synth_ray(spec, out_dir, num_shards)` runs the shards as Ray tasks.
`matedit.edit(photo, material)` makes the object in a photo of another material, like
`matedit edit` (docs/edit.md).
"""

from __future__ import annotations

import os
import tempfile
import threading

import numpy as np

# Without it the Vulkan loader prints "XDG_RUNTIME_DIR is invalid" lines while looking for
# a GPU on headless machines; the variable has no other use here (the CLI does the same).
os.environ.setdefault("XDG_RUNTIME_DIR", tempfile.gettempdir())

from ._matedit import (
    Renderer,
    bumpy,
    load_env,
    load_normals,
    preset,
    presets,
    random_material,
    sky,
    shape_normals,
    procedural_env,
    sphere,
    synth,
    synth_check,
    synth_verify,
    builtin_weights,
    edit_photo,
)

__all__ = [
    "Renderer",
    "render",
    "backward",
    "default_renderer",
    "presets",
    "preset",
    "load_env",
    "load_normals",
    "sphere",
    "bumpy",
    "random_material",
    "sky",
    "shape_normals",
    "procedural_env",
    "synth",
    "synth_check",
    "synth_verify",
    "edit",
]

_lock = threading.Lock()
_default: dict = {}


def default_renderer(device: str = "auto") -> Renderer:
    """The shared renderer for `device`, made on first use."""
    with _lock:
        r = _default.get(device)
        if r is None:
            r = Renderer(device)
            _default[device] = r
        return r


def _f32(name: str, a) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.float32:
        raise ValueError(f"{name}: dtype {a.dtype}, expected float32")
    return a


def _ctrl(a) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype not in (np.float32, np.float64):
        raise ValueError(f"ctrl: dtype {a.dtype}, expected float64 or float32")
    return a.astype(np.float64, copy=False)


def render(normals, env, ctrl, *, fov=None, convention="equirect", device="auto", tolerance=None):
    """The image(s), float32 (H, W, 3) or (B, H, W, 3).

    fov: vertical field of view in degrees of a perspective camera (None: orthographic).
    convention: "equirect" or "paper". device: "auto", "cpu", "gpu" or "reference".
    tolerance: None for the exact layer, or the relative error a level of detail may have.
    """
    return default_renderer(device).render(
        _f32("normals", normals),
        _f32("env", env),
        _ctrl(ctrl),
        fov=fov,
        convention=convention,
        tolerance=tolerance,
    )


def backward(
    normals, env, ctrl, upstream, *, fov=None, convention="equirect", device="auto", tolerance=None, wanted=None
):
    """(d_env, d_normals, d_ctrl), float32, for dLoss/dImage `upstream`. With `wanted` (some of
    "env", "normals", "ctrl") only those are computed and the others are zeros."""
    return default_renderer(device).backward(
        _f32("normals", normals),
        _f32("env", env),
        _ctrl(ctrl),
        _f32("upstream", upstream),
        fov=fov,
        convention=convention,
        tolerance=tolerance,
        wanted=None if wanted is None else [wanted] if isinstance(wanted, str) else list(wanted),
    )


def _photo(name: str, a) -> np.ndarray:
    """A photo as linear float32 (H, W, 3): 8-bit sRGB (uint8) is linearised."""
    a = np.asarray(a)
    if a.dtype == np.uint8:
        x = a.astype(np.float32) / 255
        a = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)
    if a.dtype != np.float32:
        raise ValueError(f"{name}: dtype {a.dtype}, expected float32 (linear) or uint8 (sRGB)")
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: {int((~np.isfinite(a)).sum())} values are NaN or infinite")
    return a


def edit(photo, material=None, *, like=None, mask=None, like_mask=None, steps=None, weights=None, device="auto", box=None, points=None, detail=1.0,
         mirror=True, normals=None, env=None, like_env=None, like_steps=None) -> dict:
    """The object in `photo` made of another material, as `matedit edit` does (docs/edit.md).

    photo: (H, W, 3), linear float32 or 8-bit sRGB (uint8). material: a preset name or
    control points (108,); or like: another photo, whose material is predicted and refined.
    mask (and like_mask): (H, W) bool, the object; None: the nets find it (a ValueError
    "no single object found" where none stands out). box: (x0, y0, x1, y1) in pixels
    around the object (x1, y1 exclusive); points: [(x, y), ...] on the object, (x, y, False)
    off it: the object is cut out where pointed at, as `matedit edit --box/--point/--not`.
    steps: refinement steps (0: the predictions alone; None: 20, or 100 with both normals and
    env known). weights: a weights file (None: the
    built-in nets).
    detail: how much of the photo's own detail the edit keeps, 0 to 1 (1: the photo with the
    shading changed to the new material's; 0: the re-rendered object alone). mirror: the nets
    also see the photo mirrored left to right and their answers are averaged (False: half
    the nets' time, as `matedit edit --no-mirror`). normals: (H, W, 3) float32, the object's
    normals known otherwise (camera frame; a zero normal takes the nets'), and env: (h, w, 3)
    float32, a known lat-long light in the photo's units (the nets' 16 x 32 dividing it; only
    the material is refined, and edits render under it unblurred), as `--normals` and `--env`;
    like_env: the like photo's light, as `--like-env`; like_steps: the like photo's
    refinement steps (None: as `steps`), as `--like-steps`.

    Returns a dict: "edit" (H, W, 3) linear, "mask" and "alpha" (H, W), "normals" at the
    crop (S, S, 3) and "crop" (x0, y0, S), "env" (the refined light, blurred as edits
    render under it; or the known light), "material" and "predicted_material" (108,) of the photo's object,
    "psnr_predicted" and "psnr_refined" (dB, the re-rendered photo against the photo, with
    the light before its blur), "losses", "seconds".
    """
    photo = _photo("photo", photo)
    if (material is None) == (like is None):
        raise ValueError("give material or like, not both and not neither")
    if like is not None:
        grey = preset("matte-white")
        known = None if like_env is None else np.ascontiguousarray(like_env, dtype=np.float32)
        k = steps if like_steps is None else like_steps
        m = edit_photo(_photo("like", like), grey, like_mask, k, weights, device, mirror=mirror, env=known)["material"]
    elif isinstance(material, str):
        m = preset(material)
    else:
        m = _ctrl(material)
    mask = None if mask is None else np.asarray(mask, dtype=bool)
    bounds = None if box is None else tuple(int(v) for v in box)
    pts = None
    if points is not None:
        pts = []
        for p in points:
            if len(p) not in (2, 3):
                raise ValueError(f"points: {p!r} is not (x, y) or (x, y, on_object)")
            pts.append((int(p[0]), int(p[1]), bool(p[2]) if len(p) == 3 else True))
    known = [None if a is None else np.ascontiguousarray(a, dtype=np.float32) for a in (normals, env)]
    return edit_photo(photo, np.ascontiguousarray(m), mask, steps, weights, device, bounds, pts, detail, mirror, *known)
