# The shipped model: run (a) (a.py, the better run on the validation split) trained three times
# as long, 12000 steps (about 6 passes over data/train); docs/nets_card.md.
#   python -m matedit.nets.train long.py --out runs/long      # --resume after a stop
#   python -m matedit.nets.evaluate runs/long/weights.safetensors data/test
import pathlib as _pathlib

exec((_pathlib.Path(__file__).parent / "a.py").read_text())
steps = 12000
