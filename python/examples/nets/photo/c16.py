# Photo-like training on a GPU (docs/nets.md, "Training on a GPU"): the shipped nets' size from a random start.
#   bash device.sh SECONDS c16 ...          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train c16.py --out runs/c16     anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

data = "data/train"  # matedit synth train.json -o data/train (device.sh: the folder it grows)
init = ""
width = 16
lr = 2e-3
