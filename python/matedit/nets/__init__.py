"""The networks of the material-editing pipeline (Liu et al., ICCV 2017) in PyTorch:
`model` (the normals, material and light nets, the input convention, safetensors weights),
`data` (streaming `matedit synth` chunks), `train` (`python -m matedit.nets.train CONFIG`),
`evaluate` (`python -m matedit.nets.evaluate WEIGHTS DATA`) and `baselines`. docs/nets.md
has the walk-through."""

from .model import Nets, NetsConfig, load, normalise, prepare, save, srgb_to_linear

__all__ = ["Nets", "NetsConfig", "load", "normalise", "prepare", "save", "srgb_to_linear"]
