# Photo-like and the paper's kind of samples at once, on a GPU (docs/nets.md, "Training on a GPU"): a16 trained further.
#   bash device.sh SECONDS m16 ...          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train m16.py --out runs/m16     anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

# half of each batch from each: matedit synth train.json -o data/train, paper128.json -o data/paper
data = ["data/train", "data/paper"]
init = "weights/a16.safetensors"  # git show 2efad6a:python/examples/nets/photo/weights/a16.safetensors > weights/a16.safetensors
width = 16
lr = 1e-3
