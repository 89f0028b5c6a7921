# The settings every run of this folder shares (a config takes them with `from gpu import *`
# and sets its own data, start, width and learning rate): one lent GPU, the data resident
# there and followed as a synth writes it, bf16, the torch layer.
import json as _json
import pathlib as _pathlib

import matedit as _matedit

levels = 4
frame = "photo"  # photo-like frames: an edit shows the nets a photo at its own shape
steps = 16000
batch_size = 64
warmup = 200
seed = 3
device = "cuda"
resident = True
follow = 100
amp = "bf16"
layer = "torch"
threads = 1
log_every = 100
checkpoint_every = 2000
checkpoint_seconds = 120.0
# the material net mixes the training presets only: those test.json draws from are held out
_held = _json.loads((_pathlib.Path(__file__).parent / "test.json").read_text())["materials"][0]["from"]
basis = [n for n in _matedit.presets()[:90] if n not in _held]
