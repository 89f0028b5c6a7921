"""The rendering layer's forward in plain torch ops (orthographic camera, the plain layer:
no continuous light, no levels of detail), on any device, differentiable by autograd.

    scene = Scene(normals, envs)        # normals (H, W, 3); envs (P, H_L, W_L, 3)
    images = scene.render_all(ctrl)     # ctrl (B, 108) -> (B, P, H, W, 3)
    image = render(normals, env, ctrl)  # zipped batches, like matedit.torch.render

The math is docs/CONVENTIONS.md's, as src/reference/ evaluates it. With an orthographic
camera the half vector, theta_d and the spline weights depend on the texel alone, and the
lobe argument x = h . n on the pixel-texel pair alone, so a `Scene` computes them once (in
float64): per pair ln x and the weight L(i) d_omega_i max(0, n . w_i), per texel the spline
basis. A render is then, per colour channel and lobe, exp(m1 ln x) and expm1(m0 x^m1) over
the pairs, and a batched matmul over the texels. The pair terms are computed in chunks of
at most `CHUNK` numbers and recomputed in the backward pass instead of being stored.
"""

from __future__ import annotations

import math

import torch

HALF_VECTOR_EPS = 1e-6  # |w_i + w_p| below this: h = 0 (src/prepare.rs)
BACKGROUND_EPS = 1e-6  # |n| below this: background (src/normals.rs)
LN_TINY = math.log(1e-30)  # ln x is taken of max(x, 1e-30)
NO_LOBE = -1e30  # "ln x" of pairs with x = 0: x^m1 = exp(m1 NO_LOBE) = 0 (the floor below) for m1 > 0, 1 for m1 = 0
# m1 ln x is taken of at least this: x^m1 >= 8.8e-27 (not 0), so that m0 x^m1 stays in
# float32's normal range, where exp is fast on the CPU (4 to 10 times slower on subnormals)
LN_POW_MIN = -60.0
CHUNK = 1 << 24  # most numbers in one pair-sized temporary (64 MiB in float32)


def texels(height: int, width: int, convention: str = "equirect", device=None):
    """Directions w_i (H_L * W_L, 3) and solid angles d_omega_i (H_L * W_L,) of a lat-long
    map's texels in map order, float64."""
    r = torch.arange(height, dtype=torch.float64, device=device)[:, None].expand(height, width)
    c = torch.arange(width, dtype=torch.float64, device=device)[None, :].expand(height, width)
    if convention == "equirect":
        theta, phi = (r + 0.5) / height * math.pi, (c + 0.5) / width * 2 * math.pi
        d_omega = theta.sin() * (math.pi / height) * (2 * math.pi / width)
    elif convention == "paper":
        theta, phi = r / height * math.pi, c / width * math.pi
        d_omega = theta.sin()
    else:
        raise ValueError(f"convention {convention!r}: expected 'equirect' or 'paper'")
    w = torch.stack([phi.cos() * theta.sin(), theta.cos(), phi.sin() * theta.sin()], -1)
    return w.reshape(-1, 3), d_omega.reshape(-1)


def spline_basis(t: torch.Tensor) -> torch.Tensor:
    """The 6 quadratic clamped B-spline basis functions on [0, pi/2] at t: (..., 6), the
    closed form per span of src/spline.rs."""
    tau = t.clamp(0, math.pi / 2) * (8 / math.pi)
    s = tau.floor().clamp(max=3)
    r = tau - s
    a, c = (1 - r) ** 2, r * r
    first, last = s == 0, s == 3
    v0 = torch.where(first, a, 0.5 * a)
    v1 = torch.where(first, 0.5 * r * (4 - 3 * r), torch.where(last, 0.5 * (1 - r) * (3 * r + 1), 0.5 + r - c))
    v2 = torch.where(last, c, 0.5 * c)
    j = torch.arange(6, device=t.device)
    si = s.long()[..., None]
    return (
        (j == si) * v0[..., None] + (j == si + 1) * v1[..., None] + (j == si + 2) * v2[..., None]
    ).to(t.dtype)


def half_vectors(w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The half vectors h (T, 3) of directions w (T, 3) and w_p = (0, 0, 1) (0 where
    w = -w_p), and theta_d = atan2(|w - w_p|, |w + w_p|) (T,)."""
    wp = torch.tensor([0.0, 0.0, 1.0], dtype=w.dtype, device=w.device)
    s, d = w + wp, w - wp
    length = s.norm(dim=-1)
    h = torch.where((length < HALF_VECTOR_EPS)[:, None], 0.0, s / length.clamp_min(HALF_VECTOR_EPS)[:, None])
    return h, torch.atan2(d.norm(dim=-1), length)


def lobe_log(h: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """ln x per pair, x = max(0, h . n) for half vectors h (T, 3) and normals n (..., 3):
    (..., T), from d = 1 - h . n = (|h - n|^2 - (|n|^2 - 1)) / 2 as ln x = log1p(-d),
    at least ln 1e-30; NO_LOBE where x = 0 (or h = 0)."""
    v = h - n[..., None, :]
    d = 0.5 * (v.square().sum(-1) - (n.square().sum(-1, keepdim=True) - 1))
    ok = (d < 1) & (h != 0).any(-1)
    lnx = torch.log1p(-torch.where(ok, d, 0.0)).clamp_min(LN_TINY)
    return torch.where(ok, lnx, NO_LOBE)


class _Lobes(torch.autograd.Function):
    """I[g, p, m, e, k] = sum_t f_k(lnx[g, p, t], m0[g, k, :, m, t], m1[g, k, :, m, t]) w[g, k, p, t, e]
    with f_k = sum_s expm1(m0_s exp(m1_s lnx)). lnx (G|1, pix, T); w (G|1, 3, pix, T, E);
    m0, m1 (G, 3, 3, M, T). The pair terms are recomputed in the backward pass."""

    @staticmethod
    def forward(ctx, lnx, w, m0, m1):
        ctx.save_for_backward(lnx, w, m0, m1)
        lnx4 = lnx[:, :, None, :]
        out = []
        for k in range(3):
            f = _f(lnx4, m0[:, k], m1[:, k])
            out.append(torch.matmul(f, w[:, k]))  # (G, pix, M, T) @ (G|1, pix, T, E)
        return torch.stack(out, -1)

    @staticmethod
    def backward(ctx, grad):
        lnx, w, m0, m1 = ctx.saved_tensors
        need_lnx, need_w, need_m0, need_m1 = ctx.needs_input_grad
        lnx4 = lnx[:, :, None, :]
        lng4 = torch.where(lnx4 > NO_LOBE / 2, lnx4, 0.0)  # ln x, 0 where x = 0
        d_lnx = grad.new_zeros(grad.shape[0], *lnx.shape[1:]) if need_lnx else None
        d_w = torch.zeros((grad.shape[0],) + w.shape[1:], dtype=w.dtype, device=w.device) if need_w else None
        d_m0, d_m1 = torch.zeros_like(m0), torch.zeros_like(m1)
        for k in range(3):
            g = grad[..., k]  # (G, pix, M, E)
            if need_w:
                d_w[:, k] = torch.matmul(_f(lnx4, m0[:, k], m1[:, k]).transpose(-1, -2), g)
            df = torch.matmul(g, w[:, k].transpose(-1, -2))  # (G, pix, M, T)
            for s in range(3):
                a0, a1 = m0[:, k, s, None], m1[:, k, s, None]  # (G, 1, M, T)
                p = (a1 * lnx4).clamp_min_(LN_POW_MIN).exp_()
                u = (a0 * p).exp_().mul_(p).mul_(df)  # dI/dm0 = E x^m1
                d_m0[:, k, s] = u.sum(1)
                u.mul_(a0)  # dI/d(ln x) / m1 = E m0 x^m1
                if need_m1:
                    d_m1[:, k, s] = (u * lng4).sum(1)
                if need_lnx:
                    d_lnx += (u * a1).sum(2)
        if d_lnx is not None:
            d_lnx = d_lnx.sum_to_size(lnx.shape)
        if d_w is not None:
            d_w = d_w.sum_to_size(w.shape)
        return d_lnx, d_w, d_m0 if need_m0 else None, d_m1 if need_m1 else None


def _f(lnx4: torch.Tensor, m0: torch.Tensor, m1: torch.Tensor) -> torch.Tensor:
    """sum_s expm1(m0_s exp(m1_s lnx)) per pair: (G, pix, M, T) from lnx4 (G|1, pix, 1, T)
    and m0, m1 (G, 3, M, T)."""
    f = None
    for s in range(3):
        q = torch.mul(m1[:, s, None], lnx4).clamp_min_(LN_POW_MIN).exp_().mul_(m0[:, s, None])
        q = _expm1_(q)
        f = q if f is None else f.add_(q)
    return f


def _expm1_(q: torch.Tensor) -> torch.Tensor:
    """exp(q) - 1 in place. On the CPU |q| < 1e-12 is taken as 0 first (an absolute error
    of 1e-12 per pair): torch's CPU expm1 is 4 times slower for |q| < 1e-15, which most
    pairs far from a lobe give."""
    if q.device.type == "cpu":
        q.masked_fill_(q.abs() < 1e-12, 0)
    return q.expm1_()


class Scene:
    """What a render of `normals` under `env` needs that does not depend on the material.

    normals: (H, W, 3) or (G, H, W, 3); env: (H_L, W_L, 3) or (G', H_L, W_L, 3), float
    tensors on one device. Built from tensors that require grad, the scene carries their
    graph: build it anew for each backward pass that wants their gradients."""

    def __init__(self, normals: torch.Tensor, env: torch.Tensor, convention: str = "equirect"):
        if normals.shape[-1] != 3 or normals.dim() not in (3, 4):
            raise ValueError(f"normals: shape {tuple(normals.shape)}, expected (H, W, 3) or (B, H, W, 3)")
        if env.shape[-1] != 3 or env.dim() not in (3, 4):
            raise ValueError(f"env: shape {tuple(env.shape)}, expected (H_L, W_L, 3) or (B, H_L, W_L, 3)")
        self.shared_normals, self.shared_env = normals.dim() == 3, env.dim() == 3
        n = normals.reshape(-1, *normals.shape[-3:]).double()
        lights = env.reshape(-1, *env.shape[-3:]).double()
        self.size = tuple(n.shape[1:3])
        dev = n.device
        w, d_omega = texels(*lights.shape[1:3], convention, dev)
        h, theta_d = half_vectors(w)
        # foreground pixels of any normal map, texels with a solid angle that some pixel faces
        fg = n.detach().square().sum(-1) >= BACKGROUND_EPS**2
        self.pixels = fg.flatten(1).any(0).nonzero()[:, 0]
        n = n.flatten(1, 2)[:, self.pixels]  # (Gn, pix, 3)
        cos = torch.einsum("gpc,tc->gpt", n, w).clamp_min(0)  # (Gn, pix, T)
        used = (d_omega > 0) & (cos.detach() > 0).flatten(0, 1).any(0)
        if not lights.requires_grad:
            used &= (lights.detach() > 0).flatten(1, 2).any(-1).any(0)
        t = used.nonzero()[:, 0]
        self.n_texels = len(t)
        self.basis = spline_basis(theta_d[t])  # (T, 6)
        self.lnx = lobe_log(h[t], n)  # (Gn, pix, T)
        self.cos = cos[:, :, t]
        self.ld = lights.flatten(1, 2)[:, t] * d_omega[t, None]  # (Ge, T, 3)

    def _coefficients(self, ctrl: torch.Tensor):
        """m0, m1 (B, 3, 3, T) of ctrl (B, 108) at the texels' theta_d."""
        c = ctrl.reshape(-1, 3, 3, 2, 6)
        m = torch.einsum("bkstj,Tj->bkstT", c, self.basis.to(ctrl.dtype))
        return m[:, :, :, 0], m[:, :, :, 1]

    def _weights(self, dtype, mode: str) -> torch.Tensor:
        """L(i) d_omega_i max(0, n . w_i): (G, 3, pix, T, 1) zipped, (1, 3, pix, T, G') for
        every light."""
        cos, ld = self.cos.to(dtype), self.ld.to(dtype)
        if mode == "zip":
            w = (cos[:, None] * ld.transpose(1, 2)[:, :, None])[..., None]
        else:
            w = cos[:, None, :, :, None] * ld.permute(2, 1, 0)[None, :, None]
        return w.contiguous()  # a broadcast product keeps its inputs' strides; matmul wants these

    def _image(self, values: torch.Tensor) -> torch.Tensor:
        """(N, pix, 3) pixel values -> (N, H, W, 3) images, 0 on the background."""
        out = values.new_zeros(values.shape[0], self.size[0] * self.size[1], 3)
        out[:, self.pixels] = values
        return out.view(-1, *self.size, 3)

    def render(self, ctrl: torch.Tensor) -> torch.Tensor:
        """The images of ctrl (108,) or (B, 108), zipped with the scene's batches (one of
        size 1 is shared): (B, H, W, 3), or (H, W, 3) when nothing is batched."""
        c = ctrl.reshape(-1, 108)
        b = {len(c), len(self.lnx), len(self.ld)} - {1}
        if len(b) > 1:
            raise ValueError(f"render: batch sizes {sorted(b)} differ")
        g = b.pop() if b else 1
        m0, m1 = (m.expand(g, -1, -1, -1)[:, :, :, None] for m in self._coefficients(c))
        w = self._weights(c.dtype, "zip")
        lnx = self.lnx.to(c.dtype)
        step = max(1, CHUNK // (lnx.shape[1] * lnx.shape[2]))
        out = []
        for i in range(0, g, step):
            part = slice(i, i + step) if len(lnx) > 1 else slice(None)
            wp = slice(i, i + step) if len(w) > 1 else slice(None)
            out.append(_Lobes.apply(lnx[part], w[wp], m0[i : i + step], m1[i : i + step]))
        img = self._image(torch.cat(out)[:, :, 0, 0])
        batched = ctrl.dim() == 2 or not (self.shared_normals and self.shared_env)
        return img if batched else img[0]

    def render_all(self, ctrl: torch.Tensor) -> torch.Tensor:
        """Every material ctrl (B, 108) under every light of the scene (its normals shared):
        (B, G', H, W, 3)."""
        if len(self.lnx) > 1:
            raise ValueError("render_all: the normals must be shared (H, W, 3)")
        c = ctrl.reshape(-1, 108)
        m0, m1 = (m.permute(1, 2, 0, 3)[None] for m in self._coefficients(c))  # (1, 3, 3, B, T)
        w = self._weights(c.dtype, "all")
        lnx = self.lnx.to(c.dtype)
        step = max(1, CHUNK // (lnx.shape[1] * lnx.shape[2]))
        parts = [slice(i, i + step) for i in range(0, len(c), step)]
        out = [_Lobes.apply(lnx, w, m0[:, :, :, b], m1[:, :, :, b]) for b in parts]
        v = torch.cat(out, 2)[0]  # (pix, B, G', 3)
        return self._image(v.permute(1, 2, 0, 3).flatten(0, 1)).view(len(c), -1, *self.size, 3)


def render(normals: torch.Tensor, env: torch.Tensor, ctrl: torch.Tensor, convention: str = "equirect") -> torch.Tensor:
    """The layer's image(s) of normals (H, W, 3) or (B, H, W, 3) under env (H_L, W_L, 3) or
    (B, H_L, W_L, 3) with materials ctrl (108,) or (B, 108), batches zipped (shared inputs
    broadcast), as matedit.torch.render with an orthographic camera: (B, H, W, 3) or (H, W, 3)."""
    return Scene(normals, env, convention).render(ctrl)
