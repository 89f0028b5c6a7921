# The paper experiment, run (b): run (a) plus the rendering losses on I' and O', the only
# difference (docs/nets.md, "The experiment").
#   python -m matedit.nets.train with_render_loss.py --out runs/b       # --resume after a stop
#   python -m matedit.nets.evaluate runs/b/weights.safetensors data/test
from without_render_loss import *  # noqa: F403 (run (a)'s settings)

render_loss = True
