"""Warp kernels of warp-cloth, one module per physical effect. Kernels are pure functions of arrays."""
