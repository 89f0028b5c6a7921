"""The layer as a PyTorch operator with autograd.

    import torch, matedit, matedit.torch
    normals = torch.from_numpy(matedit.sphere(64)).requires_grad_()
    env = torch.from_numpy(matedit.sky(16, 32)).requires_grad_()
    ctrl = torch.from_numpy(matedit.preset("clay")).float().requires_grad_()
    image = matedit.torch.render(normals, env, ctrl)
    image.square().mean().backward()    # normals.grad, env.grad, ctrl.grad

`torch.ops.matedit.render` is a `torch.library.custom_op` with a fake (meta) kernel and
autograd registered, so it works under autograd and `torch.compile`; its backward is
`torch.ops.matedit.render_backward`, an op of its own. Tensors are float32, on the CPU
or on a GPU: with CUDA tensors the ops copy their inputs to host memory once through
pinned buffers, run the layer (`device="auto"` picks the wgpu GPU path where there is a
GPU), and copy the outputs back once, to the inputs' device; they say so once per process.
"""

from __future__ import annotations

import warnings

import numpy as np
import torch

import matedit

__all__ = ["render"]

_warned = False


def _np(t: torch.Tensor) -> np.ndarray:
    """A host array of `t`: on a GPU, copied once into a pinned buffer (the device copy
    can then run at full speed and without a staging copy of the driver's)."""
    t = t.detach()
    if t.device.type == "cpu":
        return t.contiguous().numpy()
    _warn_once(t.device)
    host = torch.empty(t.shape, dtype=t.dtype, pin_memory=t.device.type == "cuda")
    host.copy_(t)
    return host.numpy()


def _back(a: np.ndarray, device: torch.device) -> torch.Tensor:
    """`a` as a tensor on `device`: through a pinned buffer to a GPU."""
    t = torch.from_numpy(np.ascontiguousarray(a))
    if device.type == "cpu":
        return t
    pinned = device.type == "cuda"
    host = torch.empty(t.shape, dtype=t.dtype, pin_memory=pinned).copy_(t) if pinned else t
    return host.to(device, non_blocking=pinned)


def _warn_once(device: torch.device) -> None:
    global _warned
    if not _warned:
        _warned = True
        warnings.warn(
            f"matedit.torch: tensors on {device} are copied to host memory and back for "
            "the layer, which runs on its own device (device='auto': the wgpu GPU path "
            "where there is a GPU); warned once",
            stacklevel=3,
        )


@torch.library.custom_op("matedit::render", mutates_args=())
def _render_op(
    normals: torch.Tensor,
    env: torch.Tensor,
    ctrl: torch.Tensor,
    fov: float,
    convention: str,
    device: str,
) -> torch.Tensor:
    img = matedit.render(
        _np(normals),
        _np(env),
        _np(ctrl).astype(np.float64),
        fov=fov if fov > 0 else None,
        convention=convention,
        device=device,
    )
    return _back(img, normals.device)


def _batch(normals: torch.Tensor, env: torch.Tensor, ctrl: torch.Tensor) -> int | None:
    b = None
    if normals.dim() == 4:
        b = normals.shape[0]
    if env.dim() == 4:
        b = env.shape[0]
    if ctrl.dim() == 2:
        b = ctrl.shape[0]
    return b


@_render_op.register_fake
def _(normals, env, ctrl, fov, convention, device):
    b = _batch(normals, env, ctrl)
    h, w = normals.shape[-3], normals.shape[-2]
    shape = (b, h, w, 3) if b is not None else (h, w, 3)
    return normals.new_empty(shape)


@torch.library.custom_op("matedit::render_backward", mutates_args=())
def _backward_op(
    normals: torch.Tensor,
    env: torch.Tensor,
    ctrl: torch.Tensor,
    upstream: torch.Tensor,
    fov: float,
    convention: str,
    device: str,
    want_normals: bool = True,
    want_env: bool = True,
    want_ctrl: bool = True,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    # the gradients not wanted are zeros, and the layer skips their work
    wanted = [name for name, w in (("normals", want_normals), ("env", want_env), ("ctrl", want_ctrl)) if w]
    d_env, d_normals, d_ctrl = matedit.backward(
        _np(normals),
        _np(env),
        _np(ctrl).astype(np.float64),
        _np(upstream),
        fov=fov if fov > 0 else None,
        convention=convention,
        device=device,
        wanted=wanted,
    )
    # an input shared by the batch gets the batch's sum
    if env.dim() == 3 and d_env.ndim == 4:
        d_env = d_env.sum(0)
    if normals.dim() == 3 and d_normals.ndim == 4:
        d_normals = d_normals.sum(0)
    if ctrl.dim() == 1 and d_ctrl.ndim == 2:
        d_ctrl = d_ctrl.sum(0)
    return (
        _back(d_env, env.device),
        _back(d_normals, normals.device),
        _back(d_ctrl, ctrl.device).to(ctrl.dtype),
    )


@_backward_op.register_fake
def _(normals, env, ctrl, upstream, fov, convention, device, want_normals=True, want_env=True, want_ctrl=True):
    return normals.new_empty(env.shape), normals.new_empty(normals.shape), ctrl.new_empty(ctrl.shape)


def _setup_context(ctx, inputs, output):
    normals, env, ctrl, fov, convention, device = inputs
    ctx.save_for_backward(normals, env, ctrl)
    ctx.options = (fov, convention, device)


def _backward(ctx, grad):
    normals, env, ctrl = ctx.saved_tensors
    if not any(ctx.needs_input_grad[:3]):
        return None, None, None, None, None, None
    need = ctx.needs_input_grad
    d_env, d_normals, d_ctrl = torch.ops.matedit.render_backward(
        normals, env, ctrl, grad.contiguous(), *ctx.options, need[0], need[1], need[2]
    )
    return (
        d_normals if need[0] else None,
        d_env if need[1] else None,
        d_ctrl if need[2] else None,
        None,
        None,
        None,
    )


_render_op.register_autograd(_backward, setup_context=_setup_context)


def render(
    normals: torch.Tensor,
    env: torch.Tensor,
    ctrl: torch.Tensor,
    *,
    fov: float | None = None,
    convention: str = "equirect",
    device: str = "auto",
) -> torch.Tensor:
    """The image(s) (H, W, 3) or (B, H, W, 3), differentiable in normals, env and ctrl.

    normals (H, W, 3) or (B, H, W, 3) and env (H_L, W_L, 3) or (B, H_L, W_L, 3) are
    float32; ctrl (108,) or (B, 108) is float32 or float64. fov, convention and device are
    as for `matedit.render`.
    """
    for name, t in (("normals", normals), ("env", env), ("ctrl", ctrl)):
        if not isinstance(t, torch.Tensor):
            raise ValueError(f"{name}: a torch.Tensor is expected, not {type(t).__name__}")
    for name, t in (("normals", normals), ("env", env)):
        if t.dtype != torch.float32:
            raise ValueError(f"{name}: dtype {t.dtype}, expected torch.float32")
    if ctrl.dtype not in (torch.float32, torch.float64):
        raise ValueError(f"ctrl: dtype {ctrl.dtype}, expected torch.float32 or torch.float64")
    devices = {t.device for t in (normals, env, ctrl)}
    if len(devices) > 1:
        names = ", ".join(sorted(str(d) for d in devices))
        raise ValueError(f"normals, env and ctrl are on different devices ({names})")
    return torch.ops.matedit.render(normals, env, ctrl, float(fov or 0.0), convention, device)
