"""The three networks of the material-editing pipeline (Liu et al., ICCV 2017), their input
convention, and their weights as safetensors.

    nets = Nets(NetsConfig())                       # or matedit.nets.load("weights.safetensors")
    out = nets(x)                                   # x = prepare(image, mask): (B, 3, H, W)
    out["normals"], out["mask_logits"], out["ctrl"], out["env"]

Input convention. Images are linear HDR RGB. Light and material share a scale ambiguity
(the image of a light s L is s times the image of L), so an image is divided by its mean
over the object, s = mean(I[mask]), and the light net predicts the light divided by the same
s: `normalise(image, mask)` gives (I / s, s), and the training target is L / s. The nets then
see slog(I / s) = sign log(1 + |I / s|) (`prepare`), which keeps highlights hundreds of
times the mean within a few units. 8-bit sRGB photos are linearised first
(`srgb_to_linear`).

The parts:
- `NormalsNet`, a small U-Net: image -> unit normal per pixel in the camera frame (x right,
  y up, z towards the viewer; the output is normalised) and a foreground logit.
- `MaterialNet`: image and mask -> 108 control points as a convex mix of the 90 fitted MERL
  presets (softmax weights). Every mix is a valid material: its scales and exponents lie
  within the presets' ranges, so exponents are >= 0 (and <= 1e4, clamped against float32
  rounding) and the lobes stay near those of measured materials. Log-space exponents would
  also keep m1 >= 0, but leave the scales free, and a negative scale makes a lobe negative;
  and the presets' exponents span 0 to 1e4, a range a free regression spends its capacity
  on. A mix is not guaranteed non-negative either (13 presets have negative scales, and the
  BRDF is not linear in the control points: some of `synth`'s random mixes render slightly
  negative pixels, though no single preset does on a sphere under the built-in sky), but
  it is what `synth`'s {"random": "merl"} draws, so the training materials lie in the span
  the net can reach.
- `LightNet`: image and mask -> an HDR lat-long map (16 x 32 by default) as exp of its
  output, i.e. predicted in log space, where the sun and the sky's dark side are equally
  weighted.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

import matedit

N_MERL = 90  # matedit.presets() lists the 90 fitted MERL materials first, then hand-made ones


@dataclass
class NetsConfig:
    """The networks' sizes; saved with the weights."""

    width: int = 16  # channels of the first level; doubled per level
    levels: int = 3  # U-Net / encoder levels
    env_height: int = 16
    env_width: int = 32
    # the fitted MERL presets the material net mixes, by name; empty: all 90. A run that
    # holds materials out for testing leaves them out of the basis too.
    basis: list = field(default_factory=list)
    # the image side the nets were trained at (set by training): `matedit edit` runs them at it
    image_size: int = 64
    # how the nets saw whole photos in training: "square" (objects centred on black or an
    # environment) or "photo" (photo-like frames); an edit without a mask shows them a photo
    # padded to a square or at its own shape (docs/edit.md)
    frame: str = "square"


def basis_names(cfg: "NetsConfig") -> list[str]:
    """The presets of cfg.basis (all 90 fitted MERL materials if empty), checked."""
    merl = matedit.presets()[:N_MERL]
    names = list(cfg.basis) or merl
    bad = [n for n in names if n not in merl]
    if bad:
        raise ValueError(f"basis: {bad[0]!r} is not a fitted MERL preset (matedit.presets() lists them)")
    if len(set(names)) != len(names):
        raise ValueError("basis: a preset is named twice")
    return names


def merl_presets(names: list[str]) -> torch.Tensor:
    """The named presets' control points, (K, 108) float32."""
    return torch.from_numpy(np.stack([matedit.preset(n) for n in names])).float()


# ---------------------------------------------------------------------------------------
# inputs


def srgb_to_linear(photo) -> np.ndarray:
    """An 8-bit sRGB photo (H, W, 3) uint8 as linear RGB float32 in [0, 1] (the sRGB curve)."""
    a = np.asarray(photo)
    if a.dtype != np.uint8:
        raise ValueError(f"photo: dtype {a.dtype}, expected uint8 (8-bit sRGB)")
    _check_shape("photo", a)
    c = a.astype(np.float32) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _check_shape(name: str, a: np.ndarray) -> None:
    if a.ndim not in (3, 4) or a.shape[-1] != 3 or a.shape[-2] < 1 or a.shape[-3] < 1:
        raise ValueError(f"{name}: shape {tuple(a.shape)}, expected (H, W, 3) or (B, H, W, 3) RGB")


def check_image(name: str, image) -> torch.Tensor:
    """`image` (H, W, 3) or (B, H, W, 3), linear and finite, as a float32 tensor (B, H, W, 3);
    anything else raises ValueError naming `name`. Negative values are allowed: the layer
    renders some mixes of MERL fits slightly negative where a lobe's scale is negative."""
    if isinstance(image, torch.Tensor):
        t = image.detach().cpu()
        if t.dtype == torch.uint8:
            raise ValueError(f"{name}: uint8 values; an 8-bit photo is sRGB: linearise it with srgb_to_linear")
    else:
        try:
            a = np.asarray(image)
        except Exception as e:  # e.g. ragged nested lists
            raise ValueError(f"{name}: not an image ({e})") from None
        if a.dtype.kind not in "fiu":
            raise ValueError(f"{name}: not an image (a {type(image).__name__} of dtype {a.dtype})")
        if a.dtype == np.uint8:
            raise ValueError(f"{name}: uint8 values; an 8-bit photo is sRGB: linearise it with srgb_to_linear")
        t = torch.from_numpy(np.ascontiguousarray(a))
    if not t.is_floating_point():
        t = t.float()
    _check_shape(name, t)
    t = t.float()
    if t.dim() == 3:
        t = t[None]
    if not torch.isfinite(t).all():
        raise ValueError(f"{name}: {int((~torch.isfinite(t)).sum())} values are NaN or infinite")
    return t


def normalise(image: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(image / s, s) with s (B,) the mean of max(image, 0) over the mask (B, H, W); a
    black object (s = 0) keeps its image (s = 1)."""
    m = mask.to(image.dtype)[..., None]
    s = (image.clamp_min(0) * m).sum((1, 2, 3)) / (3 * m.sum((1, 2, 3))).clamp_min(1)
    s = torch.where(s > 0, s, torch.ones_like(s))
    return image / s[:, None, None, None], s


def prepare(image: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """The nets' input (B, 3, H, W): slog of the image normalised by its masked mean
    (the whole image's mean without a mask). image: (B, H, W, 3), normalised or not."""
    if mask is None:
        mask = torch.ones(image.shape[:3], dtype=torch.bool, device=image.device)
    x, _ = normalise(image, mask)
    return slog(x).permute(0, 3, 1, 2).contiguous()


def slog(x: torch.Tensor) -> torch.Tensor:
    """sign(x) log(1 + |x|): log1p for images, odd so that negative pixels stay finite."""
    return torch.sign(x) * torch.log1p(x.abs())


def check_sizes(cfg: "NetsConfig", image: torch.Tensor, env: torch.Tensor, where: str) -> None:
    """ValueError naming `where` unless images (B, H, W, 3) fit the U-Net (H and W multiples
    of 2^(levels - 1)) and maps (B, H_L, W_L, 3) are the light net's size."""
    k = 2 ** (cfg.levels - 1)
    if image.shape[1] % k or image.shape[2] % k:
        raise ValueError(f"{where}: image size {image.shape[1]}x{image.shape[2]} is not a multiple of {k} ({cfg.levels} levels)")
    if tuple(env.shape[1:3]) != (cfg.env_height, cfg.env_width):
        h, w = env.shape[1:3]
        raise ValueError(f"{where}: env size {h}x{w}, the light net's is {cfg.env_height}x{cfg.env_width}")


# ---------------------------------------------------------------------------------------
# layers


def block(cin: int, cout: int) -> nn.Sequential:
    """Two 3x3 convolutions with group norm and ReLU."""
    groups = math.gcd(cout, 8)
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, padding=1),
        nn.GroupNorm(groups, cout),
        nn.ReLU(inplace=True),
        nn.Conv2d(cout, cout, 3, padding=1),
        nn.GroupNorm(groups, cout),
        nn.ReLU(inplace=True),
    )


class Encoder(nn.Module):
    """`levels` blocks, each followed by 2x2 max pooling but the last; returns every level."""

    def __init__(self, cin: int, width: int, levels: int):
        super().__init__()
        chans = [width * 2**i for i in range(levels)]
        self.blocks = nn.ModuleList(block(a, b) for a, b in zip([cin] + chans[:-1], chans))
        self.channels = chans

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        feats = []
        for i, b in enumerate(self.blocks):
            x = b(x if i == 0 else F.max_pool2d(x, 2))
            feats.append(x)
        return feats


class NormalsNet(nn.Module):
    """A U-Net: (B, 3, H, W) -> normals (B, H, W, 3), unit length, and mask logits (B, H, W).
    H and W must be multiples of 2^(levels - 1)."""

    def __init__(self, cfg: NetsConfig):
        super().__init__()
        self.enc = Encoder(3, cfg.width, cfg.levels)
        ch = self.enc.channels
        self.up = nn.ModuleList(nn.ConvTranspose2d(ch[i + 1], ch[i], 2, stride=2) for i in range(len(ch) - 1))
        self.dec = nn.ModuleList(block(2 * ch[i], ch[i]) for i in range(len(ch) - 1))
        self.head = nn.Conv2d(ch[0], 4, 1)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feats = self.enc(x)
        y = feats[-1]
        for i in reversed(range(len(self.dec))):
            y = self.dec[i](torch.cat([self.up[i](y), feats[i]], 1))
        out = self.head(y).permute(0, 2, 3, 1)
        # a bias towards +z (facing the viewer) so that the first normals are plausible
        n = out[..., :3] + out.new_tensor([0.0, 0.0, 1.0])
        return F.normalize(n, dim=-1, eps=1e-6), out[..., 3]


class GlobalNet(nn.Module):
    """An encoder on image and mask (4 channels), average pooling over the object and over
    the whole image, and a two-layer head with `nout` outputs. It sees the background too:
    where a dataset shows the light map or a photo behind the object, that is evidence."""

    def __init__(self, cfg: NetsConfig, nout: int):
        super().__init__()
        self.enc = Encoder(4, cfg.width, cfg.levels)
        c = self.enc.channels[-1]
        self.head = nn.Sequential(nn.Linear(2 * c, 4 * c), nn.ReLU(inplace=True), nn.Linear(4 * c, nout))

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m = mask.to(x.dtype)[:, None]
        f = self.enc(torch.cat([x, m], 1))[-1]
        mf = F.adaptive_avg_pool2d(m, f.shape[-2:])
        on_object = (f * mf).sum((2, 3)) / mf.sum((2, 3)).clamp_min(1e-6)
        return self.head(torch.cat([on_object, f.mean((2, 3))], 1))


class MaterialNet(nn.Module):
    """(B, 3, H, W) and mask (B, H, W) -> ctrl (B, 108) = softmax(logits) @ the basis presets."""

    def __init__(self, cfg: NetsConfig):
        super().__init__()
        names = basis_names(cfg)
        self.net = GlobalNet(cfg, len(names))
        self.register_buffer("presets", merl_presets(names))
        # idx(k, s, t, j) = ((k * 3 + s) * 2 + t) * 6 + j: t = 1 are the exponents
        self.register_buffer("is_exponent", torch.arange(108) // 6 % 2 == 1, persistent=False)

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.mix(self.weights(x, mask))

    def weights(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """The softmax weights (B, K) of the basis presets."""
        return torch.softmax(self.net(x, mask), -1)

    def mix(self, w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(ctrl, w) of softmax weights w (B, K)."""
        ctrl = w @ self.presets
        # weights summing to 1 + 1e-7 in float32 would put a mix of 1e4 exponents just over
        # the layer's bound of 1e4
        return torch.where(self.is_exponent, ctrl.clamp(0, 1e4), ctrl), w


class LightNet(nn.Module):
    """(B, 3, H, W) and mask (B, H, W) -> light (B, H_L, W_L, 3) = exp(output), in units of
    the image's masked mean (see `normalise`)."""

    def __init__(self, cfg: NetsConfig):
        super().__init__()
        self.shape = (cfg.env_height, cfg.env_width, 3)
        self.net = GlobalNet(cfg, math.prod(self.shape))

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return torch.exp(self.log(x, mask))

    def log(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """The log of the light, clamped to [-20, 20]."""
        return self.net(x, mask).view(-1, *self.shape).clamp(-20, 20)


# x -> -x in the camera frame: the normals of an image mirrored left to right
MIRROR = (-1.0, 1.0, 1.0)


def mirror_env(env: torch.Tensor) -> torch.Tensor:
    """The light (B, H_L, W_L, 3) of an image mirrored left to right: x -> -x takes the
    equirect azimuth phi to pi - phi, column c to (W_L / 2 - 1 - c) mod W_L."""
    w = env.shape[2]
    return env[:, :, (w // 2 - 1 - torch.arange(w, device=env.device)) % w]


class Nets(nn.Module):
    """The three nets, and the mean log light of the training data (the mean-light
    baseline, accumulated during training)."""

    def __init__(self, cfg: NetsConfig):
        super().__init__()
        if cfg.frame not in ("square", "photo"):
            raise ValueError(f"frame: {cfg.frame!r} is not 'square' or 'photo'")
        self.cfg = cfg
        self.normals = NormalsNet(cfg)
        self.material = MaterialNet(cfg)
        self.light = LightNet(cfg)
        self.register_buffer("log_light_sum", torch.zeros(cfg.env_height, cfg.env_width, 3, dtype=torch.float64))
        self.register_buffer("light_count", torch.zeros((), dtype=torch.float64))

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None = None, mirror: bool = False) -> dict:
        """x = prepare(image, mask); the material and light nets see `mask`, or the
        predicted mask without one. With `mirror`, each net also sees the image mirrored
        left to right, and the two answers are averaged, the mirrored one mirrored back:
        the normals (renormalised), the mask logits, the material's weights, the light's log."""
        n, logits = self.mask_and_normals(x, mirror)
        if mask is None:
            mask = logits > 0
        w = self.material.weights(x, mask)
        log_env = self.light.log(x, mask)
        if mirror:
            xm, mm = x.flip(-1), mask.flip(-1)
            w = (w + self.material.weights(xm, mm)) / 2
            log_env = (log_env + mirror_env(self.light.log(xm, mm))) / 2
        ctrl, w = self.material.mix(w)
        return {"normals": n, "mask_logits": logits, "ctrl": ctrl, "weights": w, "env": torch.exp(log_env)}

    def mask_and_normals(self, x: torch.Tensor, mirror: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """The normals net's (normals, mask logits) of x; with `mirror`, averaged with those
        of the mirrored image (see `forward`)."""
        n, logits = self.normals(x)
        if mirror:
            nm, lm = self.normals(x.flip(-1))
            n = F.normalize(n + nm.flip(2) * n.new_tensor(MIRROR), dim=-1, eps=1e-6)
            logits = (logits + lm.flip(-1)) / 2
        return n, logits

    def mean_light(self) -> torch.Tensor:
        """The geometric mean of the training lights seen (normalised), (H_L, W_L, 3), as the
        light loss measures: exp(mean log(L / s + 1e-3)) - 1e-3. Without training, ones."""
        mean = torch.exp(self.log_light_sum / self.light_count.clamp_min(1)) - 1e-3
        return torch.where(self.light_count > 0, mean.clamp_min(0), torch.ones_like(mean)).float()

    @torch.no_grad()
    def predict(self, image, mask=None, mirror: bool = False) -> dict:
        """Normals, mask, material and light of a linear HDR image (H, W, 3) or (B, H, W, 3),
        as NumPy arrays; the light is in the image's units (times s). mask: (H, W) or
        (B, H, W), or None to use the predicted one. mirror: average with the mirrored
        image's answers (see `forward`)."""
        was = self.training
        try:
            self.eval()
            return self._predict(image, mask, mirror)
        finally:
            self.train(was)

    def _predict(self, image, mask, mirror: bool) -> dict:
        img = check_image("image", image).to(self.log_light_sum.device)
        k = 2 ** (self.cfg.levels - 1)
        if img.shape[1] % k or img.shape[2] % k:
            raise ValueError(f"image: size {img.shape[1]}x{img.shape[2]} is not a multiple of {k}")
        if mask is not None:
            m = torch.as_tensor(np.asarray(mask)).bool().to(img.device)
            given = tuple(m.shape)
            m = m[None] if m.dim() == 2 else m
            if m.shape != img.shape[:3]:
                want = tuple(img.shape[:3]) if len(given) != 2 else tuple(img.shape[1:3])
                raise ValueError(f"mask: shape {given}, expected {want}")
        else:
            m = self.mask_and_normals(prepare(img), mirror)[1] > 0
        x = prepare(img, m)
        out = self(x, m, mirror)
        _, s = normalise(img, m)
        single = np.asarray(image).ndim == 3 if not isinstance(image, torch.Tensor) else image.dim() == 3
        res = {
            "normals": (out["normals"] * m[..., None]).numpy(),
            "mask": m.numpy(),
            "ctrl": out["ctrl"].double().numpy(),
            "env": (out["env"] * s[:, None, None, None]).numpy(),
        }
        return {k: v[0] for k, v in res.items()} if single else res


# ---------------------------------------------------------------------------------------
# judging a material by its images

PROBE_LIGHTS = ("sun-sky", "studio", "indoor")


def probe_scene(size: int = 32, env_height: int = 16, env_width: int = 32) -> tuple[torch.Tensor, torch.Tensor]:
    """A sphere's normals (size, size, 3) and three fixed probe lights (3, H_L, W_L, 3): the
    procedural sun-sky, studio and indoor lights of seed 0, each scaled to mean 1."""
    envs = np.stack([matedit.procedural_env(k, 0, env_height, env_width) for k in PROBE_LIGHTS])
    envs /= envs.mean(axis=(1, 2, 3), keepdims=True)
    return torch.from_numpy(matedit.sphere(size)), torch.from_numpy(envs)


def spheres(ctrl: torch.Tensor, probe, device: str = "cpu", backend: str = "rust") -> torch.Tensor:
    """The materials ctrl (B, 108) on the probe's sphere under each probe light:
    (B, P, size, size, 3), differentiable in ctrl. backend "rust": matedit.torch.render on
    the layer's `device`; "torch": matedit.nets.layer in torch ops on ctrl's device (`probe`
    may then be a prepared layer.Scene of the probe's tensors, built once)."""
    if backend == "torch":
        from matedit.nets import layer

        scene = probe if isinstance(probe, layer.Scene) else layer.Scene(*probe)
        return scene.render_all(ctrl)
    if backend != "rust":
        raise ValueError(f"spheres: backend {backend!r}, expected 'rust' or 'torch'")
    import matedit.torch

    normals, envs = probe
    b, p = ctrl.shape[0], envs.shape[0]
    img = matedit.torch.render(
        normals, envs.repeat(b, 1, 1, 1), ctrl.repeat_interleave(p, 0).contiguous(), device=device
    )
    return img.view(b, p, *img.shape[1:])


# ---------------------------------------------------------------------------------------
# weights


def save(nets: Nets, path, extra: dict | None = None) -> None:
    """The weights as safetensors, with the config (and `extra`) as JSON metadata."""
    from safetensors.torch import save_file

    meta = {"format": "matedit-nets 1", "config": json.dumps(asdict(nets.cfg))}
    meta.update({k: json.dumps(v) for k, v in (extra or {}).items()})
    state = {k: v.detach().cpu().contiguous() for k, v in nets.state_dict().items()}
    save_file(state, str(path), metadata=meta)


def load(path=None) -> Nets:
    """Nets from a safetensors file written by `save` (or by `python -m matedit.nets.train`);
    without a path, the built-in nets (data/nets/weights.safetensors, the ones `matedit
    edit` runs; docs/nets_card.md)."""
    from safetensors import safe_open

    if path is None:
        import struct

        from safetensors.torch import load as load_bytes

        raw = matedit.builtin_weights()
        header = struct.unpack("<Q", raw[:8])[0]
        meta = json.loads(raw[8 : 8 + header]).get("__metadata__", {})
        state, path = load_bytes(raw), "data/nets/weights.safetensors (built in)"
    else:
        try:
            with safe_open(str(path), framework="pt") as f:
                meta = f.metadata() or {}
                state = {k: f.get_tensor(k) for k in f.keys()}
        except FileNotFoundError:
            raise ValueError(f"{path}: no such file") from None
        except Exception as e:
            raise ValueError(f"{path}: not a safetensors file ({e})") from None
    if meta.get("format") != "matedit-nets 1":
        raise ValueError(f"{path}: not matedit nets weights (metadata format {meta.get('format')!r})")
    known = {f.name for f in fields(NetsConfig)}
    cfg = NetsConfig(**{k: v for k, v in json.loads(meta["config"]).items() if k in known})
    try:
        nets = Nets(cfg)
    except ValueError as e:
        raise ValueError(f"{path}: metadata config: {e}") from None
    try:
        nets.load_state_dict(state)
    except RuntimeError as e:
        raise ValueError(f"{path}: weights do not fit the config: {str(e).splitlines()[0]}") from None
    return nets
