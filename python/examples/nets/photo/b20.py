# Photo-like training on a GPU (docs/nets.md, "Training on a GPU"): wider nets from a random start.
#   bash device.sh SECONDS b20 ...          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train b20.py --out runs/b20     anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

data = "data/train"  # matedit synth train.json -o data/train (device.sh: the folder it grows)
init = ""
width = 20
lr = 2e-3
