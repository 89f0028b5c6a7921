"""A contact sheet of `matedit edit` without a prompt on the photo-like set: per scene, the
photo with the true mask's outline, the mask the edit found (green where it is right, red
where it took too much, blue where it missed), the edit and the true edit.

    python evaluate.py --matedit target/release/matedit --set SET --out EVAL --extra "..."
    python sheet.py --set SET --eval EVAL --out sheet.png [--height 160]

Reads SET/NNN/{photo,mask,edit_true}.png, EVAL/NNN/nomask/{mask,edit}.png and
EVAL/results.json (the scene's IoU without a prompt); a refused scene shows its photo alone.
"""

import argparse
import json
import os

import numpy as np
from PIL import Image, ImageDraw


def load(path, size):
    return Image.open(path).convert("RGB").resize(size, Image.BILINEAR)


def outline(mask):
    """The pixels of `mask` (bool H x W) with a neighbour off it."""
    inner = mask.copy()
    inner[1:] &= mask[:-1]
    inner[:-1] &= mask[1:]
    inner[:, 1:] &= mask[:, :-1]
    inner[:, :-1] &= mask[:, 1:]
    return mask & ~inner


def found_overlay(photo, truth, found):
    """The photo darkened, with right (green), extra (red) and missed (blue) pixels."""
    rgb = np.asarray(photo, dtype=np.float32) * 0.45
    for sel, colour in ((found & truth, (60, 220, 60)), (found & ~truth, (230, 50, 50)), (~found & truth, (60, 90, 240))):
        rgb[sel] = 0.35 * rgb[sel] + 0.65 * np.array(colour, dtype=np.float32)
    return Image.fromarray(rgb.clip(0, 255).astype(np.uint8))


def row(scene_dir, eval_dir, result, height):
    photo = Image.open(os.path.join(scene_dir, "photo.png")).convert("RGB")
    size = (round(photo.width * height / photo.height), height)
    photo = photo.resize(size, Image.BILINEAR)
    truth = np.asarray(Image.open(os.path.join(scene_dir, "mask.png")).convert("L").resize(size)) > 127
    with_line = np.asarray(photo).copy()
    with_line[outline(truth)] = (255, 255, 255)
    cells = [Image.fromarray(with_line)]
    nomask = os.path.join(eval_dir, "nomask")
    if os.path.exists(os.path.join(nomask, "mask.png")):
        found = np.asarray(Image.open(os.path.join(nomask, "mask.png")).convert("L").resize(size)) > 127
        cells += [found_overlay(photo, truth, found), load(os.path.join(nomask, "edit.png"), size)]
        label = f"IoU {result.get('nomask_iou', float('nan')):.2f}"
    else:
        blank = Image.new("RGB", size, (24, 24, 24))
        cells += [blank, blank]
        label = "refused"
    cells.append(load(os.path.join(scene_dir, "edit_true.png"), size))
    out = Image.new("RGB", (sum(c.width for c in cells) + 4 * (len(cells) - 1), height), (255, 255, 255))
    x = 0
    for c in cells:
        out.paste(c, (x, 0))
        x += c.width + 4
    ImageDraw.Draw(out).text((size[0] + 8, 4), label, fill=(255, 255, 255))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", required=True, help="folder of scene folders (make_set.py --out)")
    p.add_argument("--eval", required=True, help="evaluate.py's --out for that set")
    p.add_argument("--out", required=True, help="the sheet, PNG")
    p.add_argument("--height", type=int, default=160, help="pixels of a row")
    args = p.parse_args()
    with open(os.path.join(args.eval, "results.json")) as f:
        results = json.load(f)
    by_scene = {r["scene"]: r for r in results["scenes"]}
    rows = []
    for name in sorted(os.listdir(args.set)):
        scene = os.path.join(args.set, name)
        if os.path.isdir(scene) and os.path.exists(os.path.join(scene, "photo.png")):
            rows.append(row(scene, os.path.join(args.eval, name), by_scene.get(name, {}), args.height))
    width = max(r.width for r in rows)
    sheet = Image.new("RGB", (width, sum(r.height + 4 for r in rows) - 4), (255, 255, 255))
    y = 0
    for r in rows:
        sheet.paste(r, (0, y))
        y += r.height + 4
    sheet.save(args.out)
    print(f"{args.out}: {len(rows)} scenes")


if __name__ == "__main__":
    main()
