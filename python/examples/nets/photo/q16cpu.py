# q16 on a development machine's two cores, between GPU loans: the same data and start, the
# samples synthesised once beforehand (train.json with count 6144, paper128.json with count
# 3072) and held in memory, float32, a smaller batch on a shorter schedule. Its 1,000 steps
# (71 minutes) ended at p16's level, not past it (docs/nets.md, "q16 on two cores: the curve").
#   python -m matedit.nets.train q16cpu.py --out runs/q16cpu
from q16 import *  # noqa: F403 (q16's data, start, width; gpu.py's shared settings)

device = "cpu"
amp = ""
follow = 0
threads = 2
batch_size = 32
steps = 1000
warmup = 50
lr = 4e-4
log_every = 10
checkpoint_every = 100
checkpoint_seconds = 600.0
