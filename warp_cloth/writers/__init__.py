"""Frame writers: USD time samples, Houdini .poly files and the checkpoint a run can be resumed from. The
outputs are written under staging names and put in place when the run completes (see ``warp_cloth.output``),
so a failed run never replaces what was there."""

from .checkpoint import CheckpointWriter
from .poly import PolyWriter
from .usd import UsdWriter

__all__ = ["CheckpointWriter", "PolyWriter", "UsdWriter"]
