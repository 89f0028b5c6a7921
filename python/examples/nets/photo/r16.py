# p16 with the rendering losses on I' and O', the only difference: the with/without
# experiment on photo-like data (docs/nets.md, "The third session"). The torch layer renders
# 256 pixels drawn from each mask, on the GPU.
#   bash device.sh SECONDS p16 r16
import pathlib as _pathlib

exec((_pathlib.Path(__file__).parent / "p16.py").read_text())
render_loss = True
render_pixels = 256
