# Photo-like and the paper's kind of samples at once, on a GPU (docs/nets.md, "Training on a GPU"): the shipped nets trained further.
#   bash device.sh SECONDS n16 ...          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train n16.py --out runs/n16     anywhere else (device = "cpu")
import json as _json
import pathlib as _pathlib

import matedit as _matedit

# half of each batch from each: matedit synth train.json -o data/train, paper128.json -o data/paper
data = ["data/train", "data/paper"]
init = "../../../../data/nets/weights.safetensors"
width = 16
levels = 4
steps = 16000
batch_size = 64
lr = 1e-3
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
