"""Draw the rough masks of the photos in tests/data/photos from the shapes in boxes.json.

Each photo's mask is the union of ellipses (cx, cy, rx, ry) and polygons ((x, y), ...) in
pixels, measured by eye on the photo; it is written beside it as NAME_mask.png (0/255).

    python scripts/photo_set/photo_masks.py tests/data/photos
"""

import json
import os
import sys

from PIL import Image, ImageDraw


def draw_mask(size, shapes):
    mask = Image.new("L", size, 0)
    draw = ImageDraw.Draw(mask)
    for cx, cy, rx, ry in shapes["ellipses"]:
        draw.ellipse([cx - rx, cy - ry, cx + rx, cy + ry], fill=255)
    for polygon in shapes["polygons"]:
        draw.polygon([tuple(p) for p in polygon], fill=255)
    return mask


def main(folder):
    with open(os.path.join(folder, "boxes.json")) as f:
        photos = json.load(f)
    for name, entry in photos.items():
        size = Image.open(os.path.join(folder, name)).size
        out = os.path.join(folder, os.path.splitext(name)[0] + "_mask.png")
        draw_mask(size, entry["mask"]).save(out, optimize=True)
        print(f"{out}: {size[0]}x{size[1]}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/photos")
