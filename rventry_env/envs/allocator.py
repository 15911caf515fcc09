"""Keep freed heap memory in the process while the vector environment runs.

A batched step makes a few thousand short-lived NumPy temporaries of N x 8 bytes.
At N >= 8192 each is 64 KB or more, and glibc's default policy hands freed memory
back to the kernel as soon as the top of the heap exceeds 128 KB, so the next
temporary page-faults all its pages again: every array operation then costs 3-6
times its arithmetic (measured: DCM of 8192 quaternions 47 -> 8 ns per element).
Raising the trim threshold and top padding keeps that memory mapped. The effect
is process-wide (up to a few hundred MB of freed heap stays resident), which
suits a training process. It is a no-op where glibc is not the allocator.
"""

from __future__ import annotations

import ctypes
import ctypes.util

_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_done = False


def keep_freed_memory(trim_threshold: int = 256 << 20, top_pad: int = 64 << 20) -> bool:
    """Ask glibc not to return freed heap to the OS eagerly. Returns True if applied."""
    global _done
    if _done:
        return True
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    _done = bool(mallopt(_M_TRIM_THRESHOLD, trim_threshold)) and bool(mallopt(_M_TOP_PAD, top_pad))
    return _done
