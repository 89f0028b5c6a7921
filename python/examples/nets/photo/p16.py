# m16 trained further on photo-like samples with clutter and the paper's kind, on a GPU
# (docs/nets.md, "The third session"): a schedule of its own that ends within one lease.
#   bash device.sh SECONDS p16 r16          on a lent GPU machine (the runs of one session)
#   python -m matedit.nets.train p16.py --out runs/p16     anywhere else (device = "cpu")
from gpu import *  # noqa: F403 (the settings this folder's runs share)

# half of each batch from each: matedit synth train.json -o data/train, paper128.json -o data/paper
data = ["data/train", "data/paper"]
init = "weights/m16.safetensors"
width = 16
lr = 6e-4  # where m16's cosine stood when it stopped
steps = 4500
warmup = 100
