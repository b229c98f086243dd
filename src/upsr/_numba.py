"""Settings shared by the compiled (numba) kernels of every layer."""

from __future__ import annotations

__all__ = ["SAFE_FASTMATH"]

#: LLVM fast-math flags that keep NaN and ∞ semantics (NaN marks "outside", +∞ "invalid"):
#: reassociation and contraction for SIMD reductions, never "no NaNs" or "no infinities".
SAFE_FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}  # numba wants a set
