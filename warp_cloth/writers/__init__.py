"""Frame writers: USD time samples and Houdini .poly files. Each writes under a temporary name and puts
the result in place when the run finishes (also when it is interrupted), so a failed run never leaves a
half-made file where the user's previous one was."""

from .poly import PolyWriter
from .usd import UsdWriter

__all__ = ["PolyWriter", "UsdWriter"]
