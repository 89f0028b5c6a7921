# The paper experiment, run (a): the per-prediction losses only (docs/nets.md, "The experiment").
# The other configs of this folder take these settings with `from without_render_loss import *`.
#   python split.py MESHES ENVMAPS && matedit synth train.json -o data/train && matedit synth test.json -o data/test
#   python -m matedit.nets.train without_render_loss.py --out runs/a       # --resume after a stop
#   python -m matedit.nets.evaluate runs/a/weights.safetensors data/test
import json as _json
import pathlib as _pathlib

import matedit as _matedit

data = "data/train"
width = 16
levels = 4
steps = 4000
batch_size = 16
lr = 2e-3
warmup = 100
render_loss = False
seed = 1
threads = 1
workers = 0
shuffle_buffer = 256
log_every = 50
checkpoint_every = 250
# the material net mixes the training presets only: those test.json draws from are held out
_held = _json.loads((_pathlib.Path(__file__).parent / "test.json").read_text())["materials"][0]["from"]
basis = [n for n in _matedit.presets()[:90] if n not in _held]
