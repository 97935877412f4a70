"""
The same BLAS kernels on every x86-64 host, so that the detector's figures do not depend on it.

OpenBLAS chooses its kernels for the processor it finds: Haswell's on an AVX2
machine, SkylakeX's on an Intel one with AVX-512, and they add in different
orders.  The detector's least-squares fits run on them, so its figures differ
in their last bits from one host to another (all 274 judgeable records of
seeds 0-399 did, with the SkylakeX kernels forced on the project's AMD
machine), a few training records fall on the other side of a tree's
threshold, and ``make detector`` writes other trees than the shipped ones.

:func:`pin` asks OpenBLAS for its Haswell kernels, which run on every x86-64
processor with AVX2 and FMA (Intel since 2013, AMD since 2015).  OpenBLAS
reads the choice when it loads, so the package does this on import, before
NumPy or SciPy load theirs; a process that loaded NumPy first keeps its own
kernels, and :func:`kernels` says so.  Set ``STICTION_ROS_NATIVE_BLAS`` (to
anything) to keep the host's choice; on another processor nothing is pinned.
"""

from __future__ import annotations

import os
import platform
import sys

KERNEL = 'Haswell'
CORETYPE = 'OPENBLAS_CORETYPE'
NATIVE = 'STICTION_ROS_NATIVE_BLAS'
# The instructions the Haswell kernels use, as /proc/cpuinfo names them.
NEEDS = ('avx2', 'fma')

_state = 'not pinned yet'


def _cpu_flags() -> set[str]:
    try:
        with open('/proc/cpuinfo', encoding='ascii', errors='replace') as f:
            for line in f:
                if line.startswith('flags'):
                    return set(line.split(':', 1)[1].split())
    except OSError:
        pass
    return set()


def pin() -> str:
    """
    Ask OpenBLAS for its Haswell kernels where they run; return what was done.

    Returns ``KERNEL`` when pinned, otherwise the reason it was not.
    """
    global _state
    if os.environ.get(NATIVE):
        _state = f'native ({NATIVE} is set)'
    elif platform.machine().lower() not in ('x86_64', 'amd64'):
        _state = f'native (a {platform.machine()} processor)'
    elif not set(NEEDS) <= _cpu_flags():
        _state = 'native (no AVX2 and FMA, or no /proc/cpuinfo)'
    elif 'numpy' in sys.modules and os.environ.get(CORETYPE) != KERNEL:
        _state = 'native (NumPy was loaded before stiction_ros)'
    else:
        os.environ[CORETYPE] = KERNEL
        _state = KERNEL
    return _state


def kernels() -> str:
    """Return the BLAS kernels this process's figures were computed with (for cache keys)."""
    return _state
