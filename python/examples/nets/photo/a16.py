# Photo-like training on a GPU (docs/nets.md, "Training on a GPU"): the shipped nets trained further on photo-like samples.
#   bash device.sh SECONDS a16 ...          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train a16.py --out runs/a16     anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

data = "data/train"  # matedit synth train.json -o data/train (device.sh: the folder it grows)
init = "../../../../data/nets/weights.safetensors"
width = 16
lr = 1e-3
