"""Where the spread of the light's level over the background comes from in a `matedit synth`
folder of photo-like samples: log(the light's mean luminance over the sphere / the
background's mean luminance), the background being the pixels 2 or more from the object,
by kind of floor and of light, with and without a clipped background, and its correlation
with each sample's recorded draws (params.json).

    python level_spread.py SYNTH
"""

import argparse
import collections
import glob
import json
import os
import tarfile

import numpy as np
from scipy import ndimage

from level_head import background_mean, level
from matedit.nets.data import samples


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("synth")
    args = ap.parse_args()
    params = []
    for chunk in sorted(glob.glob(os.path.join(args.synth, "chunk-*.tar"))):
        with tarfile.open(chunk) as t:
            params += [json.load(t.extractfile(m)) for m in sorted(t.getnames()) if m.endswith("params.json")]
    ratio, level_log, clipped = [], [], []
    for s in samples(args.synth):
        image, mask, env = s["image"].numpy(), s["mask"].numpy(), s["env"].numpy()
        ratio.append(np.log(level(env) / background_mean(image, mask)))
        level_log.append(np.log(level(env)))
        clipped.append((image[~ndimage.binary_dilation(mask, iterations=2)].max(-1) >= 0.99).mean())
    ratio, level_log, clipped = map(np.array, (ratio, level_log, clipped))
    print(f"{len(ratio)} samples: log(light / background) median {np.exp(np.median(ratio)):.2f}, log-std {ratio.std():.3f}")

    def spread(title, keys):
        groups = collections.defaultdict(list)
        for k, r in zip(keys, ratio):
            groups[k].append(r)
        for k, v in sorted(groups.items(), key=lambda kv: str(kv[0])):
            print(f"  {title} {k}: n {len(v)}, median {np.exp(np.median(v)):.2f}, log-std {np.std(v):.3f}")

    floor = [((p.get("floor") or {}).get("floor") or {}).get("texture", {}).get("procedural", "none") for p in params]
    spread("floor", floor)
    spread("light", [p["env"].get("procedural") or os.path.basename(p["env"].get("file", "?")) for p in params])
    spread("background clipped over 1 %", list(clipped > 0.01))
    gain = np.log([p["camera_effects"].get("gain", 1.0) for p in params])
    print(f"correlation with the log of the exposure's gain: the ratio {np.corrcoef(gain, ratio)[0, 1]:+.2f}, "
          f"the light's level {np.corrcoef(gain, level_log)[0, 1]:+.2f}")
    for name, values in (("elevation", [p.get("elevation", np.nan) for p in params]),
                         ("fov", [p.get("fov", np.nan) for p in params]),
                         ("exposure stops", [p["camera_effects"].get("exposure_stops", np.nan) for p in params])):
        v = np.array(values, float)
        ok = np.isfinite(v)
        print(f"correlation of the ratio with {name}: {np.corrcoef(v[ok], ratio[ok])[0, 1]:+.2f}")


if __name__ == "__main__":
    main()
