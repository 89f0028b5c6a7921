# The paper experiment, run (b): run (a) (a.py) plus the rendering losses on I' and O', the
# only difference (docs/nets.md, "The experiment").
#   python -m matedit.nets.train b.py --out runs/b       # --resume after a stop
#   python -m matedit.nets.evaluate runs/b/weights.safetensors data/test
import pathlib as _pathlib

exec((_pathlib.Path(__file__).parent / "a.py").read_text())
render_loss = True
