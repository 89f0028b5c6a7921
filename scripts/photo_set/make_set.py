"""Render the photo-like test set: objects on textured floors under real HDR light.

Each scene is one object standing on a textured floor, lit by an HDR environment map that
is also seen beyond the floor's far edge, with 0-3 other shapes around or behind it, path
traced by Mitsuba 3 (shadows, interreflections). Per scene it writes:

    photo.png  photo.exr     the photo: sRGB 8-bit at a fixed exposure, and linear (same exposure)
    mask.png                 the object's visible pixels, 0/255 (not the floor, not the clutter)
    edit_true.png            the same scene and exposure with the object made of material M2
    swatch.png  swatch_mask.png   a sphere of M2 under another environment map, dark background
    meta.json                seed, object, materials, envmaps, camera, the object's box
    normals.npy              the object's true normals, H x W x 3 float32, matedit's camera frame
                             (x right, y up, z towards the viewer), zero off the object
    swatch_normals.npy       the swatch sphere's, the same way
    light.exr                the true light as the layer takes it: what arrives at the object's
                             centre with the object left out (the map, the floor and the clutter,
                             path traced), 32 x 64 lat-long in the camera's frame
                             (docs/CONVENTIONS.md), in the photo's linear units (exposure and
                             white balance applied)
    swatch_light.exr         the swatch's: its map as the swatch's camera sees it, the same way

Everything random comes from the scene's seed; the splits use disjoint seeds (test: even,
tune: odd) and disjoint environment maps (TEST_ENVMAPS, TUNE_ENVMAPS).

    python make_set.py --split test --count 12 --out /work/photo_set/test
"""

import argparse
import json
import math
import os
import tempfile
import time

import numpy as np
from PIL import Image

# -----------------------------------------------------------------------------
# splits, materials

ENVMAP_DIR = os.environ.get("MATEDIT_ENVMAPS", "/work/shared/data/envmaps_more")
# disjoint sets of Poly Haven maps (CC0); none of them lit the nets' training data
TEST_ENVMAPS = ["apartment", "bridge", "dawn", "esplanade", "hall", "lobby", "venice", "workshop"]
TUNE_ENVMAPS = ["forest", "lab", "park", "sky", "studio", "sunset", "warehouse"]
SPLITS = {"test": (0, TEST_ENVMAPS), "tune": (1, TUNE_ENVMAPS)}  # seed = 2 * index + offset

# the materials M2 that edits aim at, each shown on a swatch sphere
SWATCHES = {
    "gold": {"type": "roughconductor", "material": "Au", "alpha": 0.12},
    "copper": {"type": "roughconductor", "material": "Cu", "alpha": 0.25},
    "aluminium": {"type": "roughconductor", "material": "Al", "alpha": 0.06},
    "brushed-steel": {"type": "principled", "base_color": [0.62, 0.62, 0.64], "metallic": 1.0, "roughness": 0.35},
    "red-plastic": {"type": "plastic", "diffuse_reflectance": [0.55, 0.04, 0.03]},
    "blue-rough-plastic": {"type": "roughplastic", "diffuse_reflectance": [0.04, 0.10, 0.45], "alpha": 0.2},
    "green-ceramic": {"type": "plastic", "diffuse_reflectance": [0.08, 0.35, 0.12]},
    "white-clay": {"type": "diffuse", "reflectance": [0.78, 0.75, 0.70]},
    "black-rubber": {"type": "roughplastic", "diffuse_reflectance": [0.03, 0.03, 0.03], "alpha": 0.45},
    "yellow-paint": {"type": "principled", "base_color": [0.80, 0.55, 0.05], "roughness": 0.3},
}


def random_colour(rng, lo=0.05, hi=0.85):
    """An RGB reflectance: a random hue at a random value and saturation."""
    hue = rng.uniform(0, 1)
    sat = rng.uniform(0.2, 0.95)
    val = rng.uniform(lo, hi)
    rgb = np.clip(np.abs((hue * 6 + np.array([0, 4, 2])) % 6 - 3) - 1, 0, 1)
    return [round(float(c), 3) for c in val * (1 - sat + sat * rgb)]


def random_material(rng):
    """A Mitsuba BSDF with random parameters, as a JSON-able description."""
    kind = rng.choice(["diffuse", "plastic", "roughplastic", "roughconductor", "principled"])
    if kind == "diffuse":
        return {"type": "diffuse", "reflectance": random_colour(rng)}
    if kind == "plastic":
        return {"type": "plastic", "diffuse_reflectance": random_colour(rng)}
    if kind == "roughplastic":
        alpha = round(float(rng.uniform(0.05, 0.4)), 3)
        return {"type": "roughplastic", "diffuse_reflectance": random_colour(rng), "alpha": alpha}
    if kind == "roughconductor":
        alpha = round(float(rng.uniform(0.03, 0.35)), 3)
        return {"type": "roughconductor", "material": str(rng.choice(["Au", "Cu", "Al", "Ag", "Cr"])), "alpha": alpha}
    return {
        "type": "principled",
        "base_color": random_colour(rng),
        "metallic": round(float(rng.choice([0.0, 0.0, 1.0])), 3),
        "roughness": round(float(rng.uniform(0.15, 0.7)), 3),
    }


def bsdf(desc):
    """The Mitsuba scene-dict BSDF of a material description."""
    d = {k: v for k, v in desc.items() if k != "name"}
    for key in ("reflectance", "diffuse_reflectance", "base_color"):
        if key in d:
            d[key] = {"type": "rgb", "value": d[key]}
    if d["type"] == "roughconductor":
        d["distribution"] = "ggx"
    return d


# -----------------------------------------------------------------------------
# procedural floor textures (periodic, so that they tile without seams)

def periodic_noise(rng, n, beta):
    """n x n noise with a 1/f^beta spectrum, periodic, scaled to [0, 1]."""
    f = np.fft.fftfreq(n)
    radius = np.sqrt(f[:, None] ** 2 + f[None, :] ** 2)
    radius[0, 0] = 1.0
    spectrum = np.fft.fft2(rng.standard_normal((n, n))) / radius**beta
    spectrum[0, 0] = 0.0
    noise = np.real(np.fft.ifft2(spectrum))
    return (noise - noise.min()) / (noise.max() - noise.min())


def floor_texture(rng, n=512):
    """(kind, tile size in scene units, n x n x 3 uint8 sRGB): wood, tiles or cloth."""
    kind = str(rng.choice(["wood", "tiles", "cloth"]))
    y, x = np.mgrid[0:n, 0:n] / n
    base = np.array(random_colour(rng, 0.25, 0.7))
    if kind == "wood":
        base = np.array([0.45, 0.28, 0.14]) * rng.uniform(0.6, 1.4) + rng.uniform(-0.05, 0.05, 3)
        planks = int(rng.integers(3, 7))
        plank = np.floor(y * planks).astype(int)
        tint = 1 + 0.25 * rng.standard_normal(planks)[plank][..., None]
        shift = rng.uniform(0, 1, planks)[plank]
        warp = periodic_noise(rng, n, 2.0)
        grain = 0.5 + 0.5 * np.sin(2 * np.pi * (8 * ((y * planks) % 1) + 3 * warp + 5 * shift))
        fine = periodic_noise(rng, n, 0.8)
        shade = 0.75 + 0.2 * grain[..., None] + 0.1 * fine[..., None]
        gap = ((y * planks) % 1 < 0.012)[..., None]
        rgb = base * tint * shade * np.where(gap, 0.35, 1.0)
        tile = float(rng.uniform(1.2, 2.2))
    elif kind == "tiles":
        count = int(rng.integers(2, 5))
        cell = (np.floor(x * count) + np.floor(y * count) * count).astype(int)
        second = np.array(random_colour(rng, 0.2, 0.8)) if rng.uniform() < 0.5 else base
        checker = ((np.floor(x * count) + np.floor(y * count)) % 2)[..., None]
        colour = np.where(checker > 0, second, base)
        tint = 1 + 0.08 * rng.standard_normal(count * count)[cell][..., None]
        grout = np.minimum((x * count) % 1, (y * count) % 1)
        grout = np.minimum(grout, 1 - np.maximum((x * count) % 1, (y * count) % 1))[..., None] < 0.02
        stain = 0.9 + 0.2 * periodic_noise(rng, n, 1.5)[..., None]
        rgb = np.where(grout, 0.5 * base.mean(), colour * tint * stain)
        tile = float(rng.uniform(1.0, 2.0))
    else:
        threads = int(rng.integers(40, 90))
        weave = 0.5 + 0.25 * (np.sin(2 * np.pi * threads * x) * np.sign(np.sin(2 * np.pi * threads * y / 2)))
        cloud = periodic_noise(rng, n, 1.8)
        rgb = base * (0.7 + 0.3 * weave[..., None]) * (0.8 + 0.4 * cloud[..., None])
        tile = float(rng.uniform(0.8, 1.6))
    srgb = np.clip(rgb, 0, 1) ** (1 / 2.2)
    return kind, tile, (srgb * 255 + 0.5).astype(np.uint8)


# -----------------------------------------------------------------------------
# procedural meshes

def sphere_topology(point, rows=64, cols=96):
    """Vertices and triangles of a closed surface point(theta, phi) -> (x, y, z), theta
    from 0 (bottom pole) to pi (top pole), phi around; the poles are single vertices."""
    theta = np.linspace(0, np.pi, rows + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, cols, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack(point(t, p), -1).reshape(-1, 3)
    bottom = np.array(point(np.array(0.0), np.array(0.0))).reshape(1, 3)
    top = np.array(point(np.array(np.pi), np.array(0.0))).reshape(1, 3)
    verts = np.concatenate([bottom, ring, top])
    faces = []
    idx = lambda r, c: 1 + r * cols + c % cols
    for c in range(cols):
        faces.append((0, idx(0, c + 1), idx(0, c)))
        faces.append((len(verts) - 1, idx(rows - 2, c), idx(rows - 2, c + 1)))
        for r in range(rows - 2):
            a, b, d, e = idx(r, c), idx(r, c + 1), idx(r + 1, c), idx(r + 1, c + 1)
            faces += [(a, b, e), (a, e, d)]
    return verts, np.array(faces)


def orient_outward(verts, faces):
    """Flip the winding if the signed volume is negative, so that normals face out."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum()
    return faces if volume > 0 else faces[:, ::-1]


def torus(rng):
    major, minor = 1.0, float(rng.uniform(0.3, 0.5))
    u = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    v = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    r = major + minor * np.cos(vv)
    verts = np.stack([r * np.cos(uu), minor * np.sin(vv), r * np.sin(uu)], -1).reshape(-1, 3)
    nu, nv = len(u), len(v)
    faces = []
    for i in range(nu):
        for j in range(nv):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
            faces += [(a, b, c), (a, c, d)]
    return verts, np.array(faces)


def superellipsoid(rng):
    e1, e2 = rng.uniform(0.3, 1.6, 2)
    sx, sy, sz = rng.uniform(0.7, 1.2, 3)
    spow = lambda w, e: np.sign(w) * np.abs(w) ** e
    point = lambda t, p: (
        sx * spow(np.sin(t), e1) * spow(np.cos(p), e2),
        -sy * spow(np.cos(t), e1),
        sz * spow(np.sin(t), e1) * spow(np.sin(p), e2),
    )
    return sphere_topology(point)


def blob(rng):
    k = rng.integers(2, 5, 3)
    amp = rng.uniform(0.05, 0.15, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    def point(t, p):
        r = 1 + amp[0] * np.sin(k[0] * p + ph[0]) * np.sin(t) + amp[1] * np.cos(k[1] * t + ph[1]) \
            + amp[2] * np.sin(k[2] * (t + p) + ph[2]) * np.sin(t)
        return r * np.sin(t) * np.cos(p), -r * np.cos(t), r * np.sin(t) * np.sin(p)
    return sphere_topology(point)


def vase(rng):
    """A closed solid of revolution: a foot, a belly, a neck and a lip."""
    belly, neck, lip = rng.uniform(0.7, 1.0), rng.uniform(0.25, 0.45), rng.uniform(0.35, 0.6)
    height = rng.uniform(2.0, 2.8)
    def point(t, p):
        s = t / np.pi  # 0 at the bottom, 1 at the top
        profile = 0.45 + (belly - 0.45) * np.sin(np.pi * np.clip(s / 0.7, 0, 1)) ** 1.5
        profile = np.where(s > 0.7, neck + (lip - neck) * ((s - 0.7) / 0.3) ** 2, profile)
        profile = np.maximum(profile, neck * (s > 0.55))
        closing = np.sin(t) ** 0.08  # pull both poles to the axis at the very ends
        r = profile * closing
        return r * np.cos(p), height * s, r * np.sin(p)
    return sphere_topology(point, rows=80)


MESHES = {"torus": torus, "superellipsoid": superellipsoid, "blob": blob, "vase": vase}
OBJECTS = ["sphere", "cube", "cylinder", *MESHES]


def write_obj(path, verts, faces):
    with open(path, "w") as f:
        f.writelines(f"v {x:.5f} {y:.5f} {z:.5f}\n" for x, y, z in verts)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)


def fit_on_floor(verts, size):
    """Scale the mesh so that its largest side is `size` and stand it on y = 0 at x = z = 0."""
    lo, hi = verts.min(0), verts.max(0)
    verts = (verts - (lo + hi) / 2) * (size / (hi - lo).max())
    verts[:, 1] -= verts[:, 1].min()
    return verts


# -----------------------------------------------------------------------------
# the scene: a JSON-able description drawn from the seed, then Mitsuba dicts from it

def describe(seed, envmaps):
    rng = np.random.default_rng(seed)
    env, swatch_env = rng.choice(envmaps, 2, replace=False)
    m2 = str(rng.choice(list(SWATCHES)))
    scene = {
        "seed": seed,
        "object": str(rng.choice(OBJECTS)),
        "object_size": round(float(rng.uniform(0.8, 1.2)), 3),
        "object_yaw": round(float(rng.uniform(0, 360)), 2),
        "material": random_material(rng),
        "edit_material": {"name": m2, **SWATCHES[m2]},
        "envmap": str(env),
        "envmap_yaw": round(float(rng.uniform(0, 360)), 2),
        "swatch_envmap": str(swatch_env),
        "swatch_envmap_yaw": round(float(rng.uniform(0, 360)), 2),
        "fov": round(float(rng.uniform(30, 60)), 2),
        "elevation": round(float(rng.uniform(5, 35)), 2),
        "azimuth": round(float(rng.uniform(0, 360)), 2),
        "fill": round(float(rng.uniform(0.45, 0.7)), 3),  # object's share of the frame's height
        "horizon": round(float(rng.uniform(0.25, 0.8)), 3),  # floor's far edge, centre to top
        "mesh_seed": int(rng.integers(1 << 31)),
        "floor_seed": int(rng.integers(1 << 31)),
        "clutter": [],
    }
    scene["object_height"] = round(object_height(scene), 4)
    for _ in range(int(rng.integers(0, 4))):
        # around or behind the object: keep out of the 50 degrees either side of the camera
        angle = scene["azimuth"] + 180 + rng.uniform(-130, 130)
        scene["clutter"].append({
            "shape": str(rng.choice(["sphere", "cube", "cylinder"])),
            "size": round(float(rng.uniform(0.25, 0.6)), 3),
            "distance": round(float(rng.uniform(1.1, 2.6)), 3),
            "angle": round(float(angle % 360), 2),
            "yaw": round(float(rng.uniform(0, 360)), 2),
            "material": random_material(rng),
        })
    return scene


def primitive(mi, shape, size, x, z, yaw, material):
    """Shapes of a primitive of largest side `size` standing on the floor at (x, z)."""
    T = mi.ScalarTransform4f()
    r = size / 2
    if shape == "sphere":
        return [{"type": "sphere", "center": [x, r, z], "radius": r, "bsdf": material}]
    if shape == "cube":
        to_world = T.translate([x, r, z]).rotate([0, 1, 0], yaw).scale(r)
        return [{"type": "cube", "to_world": to_world, "bsdf": material}]
    # a cylinder (open in Mitsuba) with a disk on top; its foot is on the floor
    radius, height = 0.35 * size, size
    return [
        {"type": "cylinder", "p0": [x, 0, z], "p1": [x, height, z], "radius": radius, "bsdf": material},
        {"type": "disk", "to_world": T.translate([x, height, z]).rotate([1, 0, 0], -90).scale(radius),
         "bsdf": material},
    ]


def object_shapes(mi, scene, material, workdir):
    kind, size = scene["object"], scene["object_size"]
    if kind in MESHES:
        verts, faces = MESHES[kind](np.random.default_rng(scene["mesh_seed"]))
        faces = orient_outward(verts, faces)
        path = os.path.join(workdir, f"{kind}.obj")
        write_obj(path, fit_on_floor(verts, size), faces)
        to_world = mi.ScalarTransform4f().rotate([0, 1, 0], scene["object_yaw"])
        return [{"type": "obj", "filename": path, "to_world": to_world, "bsdf": material}]
    return primitive(mi, kind, size, 0.0, 0.0, scene["object_yaw"], material)


def object_height(scene):
    """The object's height: its largest side is object_size; a mesh may be flatter."""
    if scene["object"] not in MESHES:
        return scene["object_size"]
    verts, _ = MESHES[scene["object"]](np.random.default_rng(scene["mesh_seed"]))
    return float(fit_on_floor(verts, scene["object_size"])[:, 1].max())


def camera(scene, aspect):
    """Camera position and target: the object fills `fill` of the frame's height."""
    vfov = 2 * math.degrees(math.atan(math.tan(math.radians(scene["fov"] / 2)) / aspect))
    radius = 0.6 * scene["object_size"]
    target = np.array([0, 0.45 * scene["object_height"], 0])
    distance = radius / math.tan(math.radians(scene["fill"] * vfov / 2))
    el, az = math.radians(scene["elevation"]), math.radians(scene["azimuth"])
    offset = distance * np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    return target + offset, target, vfov


def floor(mi, scene, aspect, texture_path, tile):
    """A rectangle facing the camera: its near edge behind the camera, its far edge where
    `horizon` puts it in the frame (beyond the clutter), wide enough to fill the sides."""
    origin, target, vfov = camera(scene, aspect)
    height = origin[1]
    ground = math.hypot(origin[0], origin[2])
    below = math.radians(scene["elevation"] - scene["horizon"] * vfov / 2)
    far = height / math.tan(below) - ground if below > math.radians(1) else 60.0
    far = float(np.clip(far, 3.5, 60.0))
    near = ground + 2.0
    half_width = (ground + far) * math.tan(math.radians(scene["fov"] / 2)) * 1.2 + 1.0
    half_length = (near + far) / 2
    to_world = (mi.ScalarTransform4f().rotate([0, 1, 0], scene["azimuth"])
                .translate([0, 0, (near - far) / 2]).rotate([1, 0, 0], -90)
                .scale([half_width, half_length, 1]))
    to_uv = mi.ScalarTransform4f().scale([2 * half_width / tile, 2 * half_length / tile, 1])
    texture = {"type": "bitmap", "filename": texture_path, "to_uv": to_uv}
    return {"type": "rectangle", "to_world": to_world,
            "bsdf": {"type": "roughplastic", "diffuse_reflectance": texture, "alpha": 0.35}}


def sensor(mi, origin, target, fov, width, height, spp, seed, rfilter="gaussian"):
    return {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "x",
        "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=target.tolist(), up=[0, 1, 0]),
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": rfilter},
                 "pixel_format": "rgb"},
    }


def camera_frame(origin, target):
    """Rows: the camera's right, up and backward directions in world space, so that
    frame @ v is v in matedit's camera frame (x right, y up, z towards the viewer); the
    frame of Mitsuba's look_at with up y, whose own x points to the image's left."""
    forward = np.asarray(target, float) - np.asarray(origin, float)
    forward /= np.linalg.norm(forward)
    left = np.cross([0.0, 1.0, 0.0], forward)
    left /= np.linalg.norm(left)
    return np.stack([-left, np.cross(forward, left), -forward])


def load_map(mi, name):
    return np.array(mi.Bitmap(os.path.join(ENVMAP_DIR, f"{name}.exr")), dtype=np.float64)[..., :3]


def layer_light(src, yaw, frame, scale, size=(32, 64), supersample=4):
    """The lat-long map `src` (H x W x 3, as Mitsuba's envmap reads it) turned by `yaw`
    degrees about y (as `envmap` puts it in the scene) as the layer sees it from a camera
    of `frame`: a `size` lat-long map in matedit's equirect convention, each texel the
    solid-angle mean of the map's radiance over it, times `scale` (per channel). Each
    pixel of the map, split `supersample` ways a side, is carried to its texel with its
    solid angle."""
    sh, sw = src.shape[:2]
    k = supersample
    v = (np.arange(sh * k) + 0.5) / (sh * k)
    u = (np.arange(sw * k) + 0.5) / (sw * k)
    theta, phi = np.meshgrid(v * np.pi, u * 2 * np.pi, indexing="ij")
    # Mitsuba's envmap: uv = (atan2(x, -z) / 2 pi, acos(y) / pi) in its own frame
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    a = math.radians(yaw)
    turn = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    d = local @ (frame @ turn).T
    h, w = size
    rows = np.clip((np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi * h).astype(int), 0, h - 1)
    cols = np.clip((np.mod(np.arctan2(d[..., 2], d[..., 0]), 2 * np.pi) / (2 * np.pi) * w).astype(int), 0, w - 1)
    radiance = np.repeat(np.repeat(src, k, 0), k, 1)
    weight = np.sin(theta) * (np.pi / (sh * k)) * (2 * np.pi / (sw * k))
    texel = rows * w + cols
    out = np.stack([np.bincount(texel.ravel(), (radiance[..., c] * weight).ravel(), h * w) for c in range(3)], -1)
    texel_omega = np.sin((np.arange(h) + 0.5) / h * np.pi) * (np.pi / h) * (2 * np.pi / w)
    out = out.reshape(h, w, 3) / texel_omega[:, None, None]
    return (out * np.asarray(scale, float)).astype(np.float32)


def texel_directions(size, per_side, rng):
    """Directions in matedit's camera frame (docs/CONVENTIONS.md, equirect) spread over
    each texel of a `size` lat-long map: per_side^2 a texel, stratified in cos(theta) and
    phi and jittered; returned as (rows x cols x per_side^2) x 3, texel by texel."""
    h, w = size
    k = per_side
    r, c, i, j = np.meshgrid(np.arange(h), np.arange(w), np.arange(k), np.arange(k), indexing="ij")
    u = (i + rng.random(r.shape)) / k
    v = (j + rng.random(r.shape)) / k
    top, bottom = np.cos(r / h * np.pi), np.cos((r + 1) / h * np.pi)
    cos_t = top + u * (bottom - top)  # uniform in solid angle over the texel
    phi = (c + v) / w * 2 * np.pi
    sin_t = np.sqrt(np.clip(1 - cos_t ** 2, 0, 1))
    return np.stack([np.cos(phi) * sin_t, cos_t, np.sin(phi) * sin_t], -1).reshape(-1, 3)


def probe_light(mi, d, point, frame, scale, size=(32, 64), per_side=8, seed=0):
    """The light at `point` of the scene `d` (left without the object) as the layer
    takes it from a camera of `frame`: each texel of a `size` lat-long map the mean
    radiance, path traced, arriving at the point from the directions over it (the floor,
    the clutter and the map, with their shadows and bounces), times `scale` per channel."""
    import drjit as dr
    directions = texel_directions(size, per_side, np.random.default_rng(seed)) @ frame
    n = len(directions)
    scene = mi.load_dict(d)
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, n)
    origin = np.broadcast_to(np.asarray(point, dtype=np.float32), (n, 3))
    ray = mi.Ray3f(mi.Point3f(*(mi.Float(np.ascontiguousarray(origin[:, k])) for k in range(3))),
                   mi.Vector3f(*(mi.Float(directions[:, k].astype(np.float32)) for k in range(3))))
    radiance, _, _ = scene.integrator().sample(scene, sampler, ray)
    rgb = np.stack([np.array(radiance[k]) for k in range(3)], -1)
    dr.eval()
    h, w = size
    return (rgb.reshape(h, w, per_side * per_side, 3).mean(2) * np.asarray(scale, float)).astype(np.float32)


def true_normals(mi, d, frame, mask):
    """The object's shading normals in scene `d` (its first hit), in matedit's camera
    frame, zero off `mask`."""
    d = dict(d, integrator={"type": "aov", "aovs": "nn:sh_normal"})
    d["sensor"] = dict(d["sensor"], film=dict(d["sensor"]["film"], rfilter={"type": "box"}),
                       sampler=dict(d["sensor"]["sampler"], sample_count=16))
    n = render(mi, d)[..., :3] @ frame.T
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-6)
    return np.where(mask[..., None], n, 0).astype(np.float32)


def envmap(mi, name, yaw):
    return {"type": "envmap", "filename": os.path.join(ENVMAP_DIR, f"{name}.exr"),
            "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], yaw)}


def scene_dict(mi, scene, material, size, spp, workdir, texture_path, tile, mask_pass=False, no_object=False):
    """The scene with the object in `material`; with mask_pass, the object glows and
    everything else is black, so that a render is the object's visible coverage; with
    no_object, the object is left out (the floor, the clutter and the map alone)."""
    width, height = size
    origin, target, _ = camera(scene, width / height)
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}
    d = {"type": "scene", "sensor": sensor(mi, origin, target, scene["fov"], width, height, spp, scene["seed"],
                                           "box" if mask_pass else "gaussian")}
    if mask_pass:
        d["integrator"] = {"type": "path", "max_depth": 1}
        glow = {"type": "area", "radiance": {"type": "rgb", "value": [1, 1, 1]}}
        shapes = [dict(s, bsdf=black, emitter=glow) for s in object_shapes(mi, scene, black, workdir)]
    else:
        d["integrator"] = {"type": "path", "max_depth": 8}
        d["env"] = envmap(mi, scene["envmap"], scene["envmap_yaw"])
        shapes = [] if no_object else object_shapes(mi, scene, bsdf(material), workdir)
    f = floor(mi, scene, width / height, texture_path, tile)
    if mask_pass:
        f["bsdf"] = black
    shapes.append(f)
    for c in scene["clutter"]:
        a = math.radians(c["angle"])
        x, z = c["distance"] * math.sin(a), c["distance"] * math.cos(a)
        shapes += primitive(mi, c["shape"], c["size"], x, z, c["yaw"], black if mask_pass else bsdf(c["material"]))
    for i, s in enumerate(shapes):
        d[f"shape{i}"] = s
    return d


def swatch_dict(mi, scene, size, spp, material):
    """A unit sphere of the material under the swatch envmap, hidden behind it: black."""
    fov = 30.0
    distance = 1 / math.sin(math.radians(0.85 * fov / 2))
    origin, target = np.array([0.0, 0.0, distance]), np.zeros(3)
    d = {"type": "scene", "sensor": sensor(mi, origin, target, fov, size, size, spp, scene["seed"]),
         "object": {"type": "sphere", "radius": 1.0, "bsdf": material}}
    if material is None:  # the mask pass
        d["integrator"] = {"type": "path", "max_depth": 1}
        d["sensor"]["film"]["rfilter"] = {"type": "box"}
        d["object"]["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}
        d["object"]["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [1, 1, 1]}}
    else:
        d["integrator"] = {"type": "path", "max_depth": 8, "hide_emitters": True}
        d["env"] = envmap(mi, scene["swatch_envmap"], scene["swatch_envmap_yaw"])
    return d


# -----------------------------------------------------------------------------
# images

def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def to_srgb8(linear):
    c = np.clip(linear, 0, 1)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def save_png(path, array):
    Image.fromarray(array).save(path, optimize=True)


def render(mi, d):
    return np.array(mi.render(mi.load_dict(d)), dtype=np.float32)


def photo_exposure(image, mask):
    """A camera's exposure: the frame's median luminance at 0.18 (middle grey), lowered
    if that would clip more than the object's brightest 3%."""
    lum = luminance(image)
    return min(0.18 / max(np.median(lum), 1e-6), 0.9 / max(np.percentile(lum[mask], 97), 1e-6))


def white_sphere(mi, scene, env_key="swatch_envmap"):
    """Mean linear RGB of a white diffuse sphere under the scene's `env_key` map."""
    lit = dict(scene, swatch_envmap=scene[env_key], swatch_envmap_yaw=scene[env_key + "_yaw"])
    white = render(mi, swatch_dict(mi, lit, 32, 32, bsdf({"type": "diffuse", "reflectance": [1, 1, 1]})))
    small_mask = render(mi, swatch_dict(mi, lit, 32, 16, None))[..., 0] > 0.5
    return white[small_mask].mean(0)


def grey_card_exposure(white, gains=(1, 1, 1)):
    """The exposure of a swatch taken as for a grey card: a white diffuse sphere there,
    of mean linear RGB `white`, has mean 0.5 after the white balance's `gains`."""
    return 0.5 / max(float(luminance(np.asarray(white) * np.asarray(gains))), 1e-6)


def white_balance(white, seed, error):
    """A camera's white balance: per-channel gains that make a white sphere of mean linear
    RGB `white` grey, each off by a factor exp(N(0, error)) as an automatic white balance
    is (drawn from `seed`), scaled to unit luminance (a grey surface keeps its own)."""
    white = np.asarray(white, dtype=np.float64)
    gains = luminance(white) / np.maximum(white, 1e-6) * np.exp(np.random.default_rng(seed).normal(0, error, 3))
    return gains / luminance(gains)


def bounding_box(mask):
    ys, xs = np.nonzero(mask)
    return [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1]


def make_scene(mi, scene, size, spp, out, write_exr, balance_error=None):
    os.makedirs(out, exist_ok=True)
    width, height = size
    with tempfile.TemporaryDirectory() as workdir:
        kind, tile, texture = floor_texture(np.random.default_rng(scene["floor_seed"]))
        texture_path = os.path.join(workdir, "floor.png")
        save_png(texture_path, texture)
        scene["floor"] = {"texture": kind, "tile": round(tile, 3)}
        with_object = lambda material, spp, **kw: scene_dict(mi, scene, material, size, spp, workdir,
                                                             texture_path, tile, **kw)
        mask = render(mi, with_object(None, 16, mask_pass=True))[..., 0] > 0.5
        if mask.sum() < 50:
            raise RuntimeError(f"seed {scene['seed']}: the object is hidden ({mask.sum()} pixels)")
        photo = render(mi, with_object(scene["material"], spp))
        edit = render(mi, with_object(scene["edit_material"], spp))
        origin, target, _ = camera(scene, width / height)
        frame = camera_frame(origin, target)
        normals = true_normals(mi, with_object(scene["material"], spp), frame, mask)
        probe = probe_light(mi, with_object(None, spp, no_object=True), [0, 0.5 * scene["object_height"], 0],
                            frame, np.ones(3), seed=scene["seed"])
    side = min(width, height)
    swatch = render(mi, swatch_dict(mi, scene, side, spp, bsdf(scene["edit_material"])))
    swatch_mask = render(mi, swatch_dict(mi, scene, side, 16, None))[..., 0] > 0.5
    swatch_normals = true_normals(mi, swatch_dict(mi, scene, side, spp, bsdf(scene["edit_material"])),
                                  np.eye(3), swatch_mask)
    swatch_white, swatch_gains = white_sphere(mi, scene), np.ones(3)
    if balance_error is not None:
        gains = white_balance(white_sphere(mi, scene, "envmap"), [scene["seed"], 1], balance_error)
        swatch_gains = white_balance(swatch_white, [scene["seed"], 2], balance_error)
        photo, edit, swatch = photo * gains, edit * gains, swatch * swatch_gains
        scene["white_balance"] = [round(float(g), 4) for g in gains]
        scene["swatch_white_balance"] = [round(float(g), 4) for g in swatch_gains]
    exposure = photo_exposure(photo, mask)
    swatch_exposure = grey_card_exposure(swatch_white, swatch_gains)

    save_png(os.path.join(out, "photo.png"), to_srgb8(photo * exposure))
    save_png(os.path.join(out, "mask.png"), (mask * 255).astype(np.uint8))
    save_png(os.path.join(out, "edit_true.png"), to_srgb8(edit * exposure))
    save_png(os.path.join(out, "swatch.png"), to_srgb8(swatch * swatch_exposure))
    save_png(os.path.join(out, "swatch_mask.png"), (swatch_mask * 255).astype(np.uint8))
    gains = np.asarray(scene.get("white_balance", np.ones(3)))
    np.save(os.path.join(out, "normals.npy"), normals)
    np.save(os.path.join(out, "swatch_normals.npy"), swatch_normals)
    mi.Bitmap((probe * gains * exposure).astype(np.float32)).write(os.path.join(out, "light.exr"))
    # the swatch's camera looks down -z from +z with up y: its frame is the world's
    light = layer_light(load_map(mi, scene["swatch_envmap"]), scene["swatch_envmap_yaw"], np.eye(3),
                        swatch_gains * swatch_exposure)
    mi.Bitmap(light).write(os.path.join(out, "swatch_light.exr"))
    if write_exr:
        mi.Bitmap((photo * exposure).astype(np.float32)).write(os.path.join(out, "photo.exr"))
    meta = dict(scene, size=[width, height], spp=spp, exposure=round(float(exposure), 5),
                swatch_exposure=round(float(swatch_exposure), 5), box=bounding_box(mask),
                object_pixels=int(mask.sum()), clipped_fraction=round(float((photo * exposure > 1)[mask].any(-1).mean()), 4))
    with open(os.path.join(out, "meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
        f.write("\n")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--split", choices=list(SPLITS), default="test")
    p.add_argument("--count", type=int, default=12)
    p.add_argument("--size", default="320x240", help="WIDTHxHEIGHT of the photos")
    p.add_argument("--spp", type=int, default=96, help="samples per pixel")
    p.add_argument("--out", required=True, help="folder; scene i goes to OUT/NNN")
    p.add_argument("--no-exr", action="store_true", help="skip photo.exr")
    p.add_argument("--white-balance", type=float, metavar="ERROR", default=None,
                   help="balance each image for its light as a camera does, off by exp(N(0, ERROR)) a channel")
    args = p.parse_args()
    if args.white_balance is not None and not args.white_balance >= 0:
        p.error(f"--white-balance {args.white_balance}: the error is a spread, 0 or more")

    import mitsuba as mi
    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception as e:  # no usable libLLVM: the scalar variant gives the same images, slower
        print(f"make_set: llvm_ad_rgb unavailable ({e}); using scalar_rgb")
        mi.set_variant("scalar_rgb")
    size = tuple(int(v) for v in args.size.split("x"))
    offset, envmaps = SPLITS[args.split]
    t0 = time.time()
    for i in range(args.count):
        t = time.time()
        scene = describe(2 * i + offset, envmaps)
        scene["split"] = args.split
        make_scene(mi, scene, size, args.spp, os.path.join(args.out, f"{i:03d}"), not args.no_exr,
                   args.white_balance)
        print(f"{args.split} {i:03d}: seed {scene['seed']} {scene['object']} {scene['material']['type']} -> "
              f"{scene['edit_material']['name']} under {scene['envmap']}, {time.time() - t:.1f} s")
    print(f"{args.count} scenes in {time.time() - t0:.1f} s ({mi.variant()}, {args.spp} spp, {args.size})")


if __name__ == "__main__":
    main()
