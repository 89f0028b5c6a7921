# p16 with the rendering losses on I' and O', the only difference: the with/without
# experiment on photo-like data (docs/nets.md, "The third session"). The torch layer renders
# 256 pixels drawn from each mask, on the GPU.
#   bash device.sh SECONDS p16 r16
#   python -m matedit.nets.train r16.py --out runs/r16     anywhere else (device = "cpu")
from p16 import *  # noqa: F403 (p16's settings)

render_loss = True
render_pixels = 256
