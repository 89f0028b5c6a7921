# p16 trained further on train.json as it is now: vessels among the shapes (docs/nets.md, "A
# kind of shape the nets never saw") and the meshes creased at 40 degrees ("Where the
# photo-like test split's error is"), which no run has trained on yet; p16's schedule again.
#   bash device.sh SECONDS q16 ...                        on a lent GPU machine
#   python -m matedit.nets.train q16.py --out runs/q16    anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

# half of each batch from each: matedit synth train.json -o data/train, paper128.json -o data/paper
data = ["data/train", "data/paper"]
init = "weights/p16.safetensors"
width = 16
lr = 6e-4
steps = 4500
warmup = 100
