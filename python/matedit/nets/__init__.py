"""The networks of the material-editing pipeline (Liu et al., ICCV 2017) in PyTorch:
`model` (the normals, material and light nets, the input convention, safetensors weights),
`data` (streaming `matedit synth` chunks), `train` (`python -m matedit.nets.train CONFIG`)
and `evaluate` (`python -m matedit.nets.evaluate WEIGHTS DATA`, with the baselines).
docs/nets.md has the walk-through."""

import os

# The layer's CPU threads (rayon) and torch's OpenMP threads take turns within a step; with
# OpenMP's default spin-waiting, its idle threads hold the cores the layer needs (a 20-step
# run on 2 cores took 50 s with 2 threads each, 6.6 s with passive waiting; docs/nets.md).
# OpenMP reads this when torch is first imported, so it holds where matedit.nets comes first.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .model import Nets, NetsConfig, load, normalise, prepare, save, srgb_to_linear

__all__ = ["Nets", "NetsConfig", "load", "normalise", "prepare", "save", "srgb_to_linear"]
