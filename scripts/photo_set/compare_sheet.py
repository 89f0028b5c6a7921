"""A contact sheet of `matedit edit` runs side by side on the photo-like set: per scene, the
photo, the swatch, the edit of each evaluate.py run (its gain over the unedited photo
written under it) and the true edit.

    python evaluate.py --matedit BIN --set SET --out EVAL_A --runs edit
    python evaluate.py --matedit BIN --set SET --out EVAL_B --runs edit --known normals,light,material
    python compare_sheet.py --set SET --run "nets=EVAL_A" --run "all known=EVAL_B" --scenes 003,006 --out sheet.png

Reads SET/NNN/{photo,swatch,edit_true}.png, EVAL/NNN/edit/edit.png and EVAL/results.json.
"""

import argparse
import json
import os

from PIL import Image, ImageDraw


def load(path, size):
    return Image.open(path).convert("RGB").resize(size, Image.BILINEAR)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", required=True, help="the set's folder (make_set.py --out)")
    p.add_argument("--run", action="append", required=True, metavar="TITLE=EVAL",
                   help="a column: its title and an evaluate.py --out folder (repeatable)")
    p.add_argument("--scenes", required=True, help="comma-separated scene folders, e.g. 003,006")
    p.add_argument("--out", required=True, help="the PNG to write")
    p.add_argument("--height", type=int, default=150, help="pixels a row")
    args = p.parse_args()
    runs = []
    for r in args.run:
        title, sep, folder = r.partition("=")
        if not sep:
            p.error(f"--run {r}: give TITLE=EVAL")
        with open(os.path.join(folder, "results.json")) as f:
            gains = {s["scene"]: s.get("gain") for s in json.load(f)["scenes"]}
        runs.append((title, folder, gains))
    scenes = args.scenes.split(",")

    h = args.height
    first = Image.open(os.path.join(args.set, scenes[0], "photo.png"))
    w = round(h * first.width / first.height)
    label, gap = 16, 4
    titles = ["photo", "swatch"] + [t for t, _, _ in runs] + ["true edit"]
    widths = [w, h] + [w] * len(runs) + [w]
    sheet = Image.new("RGB", (sum(widths) + gap * (len(widths) - 1), label + len(scenes) * (h + label + gap)), "white")
    draw = ImageDraw.Draw(sheet)
    xs = [sum(widths[:i]) + gap * i for i in range(len(widths))]
    for x, t in zip(xs, titles):
        draw.text((x + 2, 2), t, fill="black")
    for row, scene in enumerate(scenes):
        y = label + row * (h + label + gap)
        d = os.path.join(args.set, scene)
        with open(os.path.join(d, "meta.json")) as f:
            meta = json.load(f)
        cells = [load(os.path.join(d, "photo.png"), (w, h)), load(os.path.join(d, "swatch.png"), (h, h))]
        notes = [f"{scene}: {meta['object']}", meta["edit_material"]["name"]]
        for _, folder, gains in runs:
            cells.append(load(os.path.join(folder, scene, "edit", "edit.png"), (w, h)))
            g = gains.get(scene)
            notes.append("failed" if g is None else f"{g:+.2f} dB")
        cells.append(load(os.path.join(d, "edit_true.png"), (w, h)))
        notes.append("")
        for x, cell, note in zip(xs, cells, notes):
            sheet.paste(cell, (x, y))
            draw.text((x + 2, y + h + 2), note, fill="black")
    sheet.save(args.out, optimize=True)
    print(f"wrote {args.out} ({sheet.width} x {sheet.height})")


if __name__ == "__main__":
    main()
