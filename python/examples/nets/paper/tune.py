# The shipped run (long.py) trained further: its weights as the start, a second cosine
# schedule from lr 1e-3, another data order (seed 2), batches of 32, 2 threads (docs/nets_card.md).
#   python -m matedit.nets.train long.py --out runs/long      # first
#   python -m matedit.nets.train tune.py --out runs/tune      # --resume after a stop
#   python -m matedit.nets.evaluate runs/tune/weights.safetensors data/test
from long import *  # noqa: F403 (long.py's settings)

init = "runs/long/weights.safetensors"
seed = 2
batch_size = 32
lr = 1e-3
warmup = 100
steps = 3000
threads = 2
