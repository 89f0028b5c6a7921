# The shipped model: run (a) (without_render_loss.py, the better run on the validation split)
# trained three times as long, 12000 steps (about 6 passes over data/train); docs/nets_card.md.
#   python -m matedit.nets.train long.py --out runs/long      # --resume after a stop
#   python -m matedit.nets.evaluate runs/long/weights.safetensors data/test
from without_render_loss import *  # noqa: F403 (run (a)'s settings)

steps = 12000
