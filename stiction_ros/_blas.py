"""
The same BLAS kernels on every x86-64 host, and which code the figures ran on.

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
NumPy or SciPy load theirs, overriding an ``OPENBLAS_CORETYPE`` of the
user's (the state says so); child processes inherit it.  A process that
loaded NumPy first keeps its own kernels (:func:`loaded_first`), and the
detector's feature builder warns before it computes figures for its cache
on them.  Set ``STICTION_ROS_NATIVE_BLAS`` (to anything) to keep the host's
choice; without AVX2 and FMA, off x86-64, or without ``/proc/cpuinfo`` (not
Linux) nothing is pinned.

NumPy chooses its own code for ``exp`` and ``log`` by processor too (AVX-512
or AVX2), which moves some figures by about 1e-16 (a review measured 3 of 10
records).  That is not pinned on import: NumPy's AVX2 code is slower (``exp``
five times here) for everything the user's process does.  ``make detector``
and ``make accuracy`` alone, where the bits matter, set ``NUMPY_PIN`` to
``NUMPY_ABOVE_AVX2`` on x86-64, so that NumPy runs a plain AVX2 processor's
code on any host (``make bench-detector`` times what users run: unpinned);
the feature builder warns a script that computes figures for its cache
without that (:func:`numpy_above_avx2`).  :func:`kernels` names OpenBLAS's
kernels and NumPy's enabled dispatch targets, so that cached figures are
never mixed between them.
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
# NumPy's run-time choice of code, and its dispatch targets above AVX2 (NumPy
# 2.4's names); the Makefile names them all (test/test_blas.py checks).
NUMPY_PIN = 'NPY_DISABLE_CPU_FEATURES'
NUMPY_ABOVE_AVX2 = ('X86_V4', 'AVX512_ICL', 'AVX512_SPR')

_state = 'not pinned yet'
LOADED_FIRST = 'native (NumPy was loaded before stiction_ros)'


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
    mine = os.environ.get(CORETYPE)
    if os.environ.get(NATIVE):
        _state = f'native ({NATIVE} is set)'
    elif platform.machine().lower() not in ('x86_64', 'amd64'):
        _state = f'native (a {platform.machine()} processor)'
    elif not set(NEEDS) <= _cpu_flags():
        _state = 'native (no AVX2 and FMA, or no /proc/cpuinfo)'
    elif 'numpy' in sys.modules and os.environ.get(CORETYPE) != KERNEL:
        _state = LOADED_FIRST
    else:
        os.environ[CORETYPE] = KERNEL
        _state = KERNEL if mine in (None, KERNEL) else f'{KERNEL} (over {CORETYPE}={mine})'
    if _state.startswith('native'):
        # Child processes that start afresh (spawn, forkserver) decide the same.
        os.environ[NATIVE] = '1'
    return _state


def state() -> str:
    """Return what :func:`pin` did: ``KERNEL``, or why the host's kernels were kept."""
    return _state


def loaded_first() -> bool:
    """Return True when NumPy came first and the host's kernels were kept for it."""
    return _state == LOADED_FIRST


def numpy_above_avx2() -> list[str]:
    """Return NumPy's dispatch targets above AVX2 that this process runs (``[]`` when none)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:     # NumPy 1.x keeps them elsewhere
        return []
    return [t for t in NUMPY_ABOVE_AVX2 if t in __cpu_dispatch__ and __cpu_features__.get(t)]


def kernels() -> str:
    """
    Return what this process's figures were computed with (for cache keys).

    The pin's state, each loaded OpenBLAS's kernels and version, and NumPy's
    enabled dispatch targets.  NumPy and SciPy are loaded here, so the
    answer does not change with what was loaded before.
    """
    import numpy as np
    import scipy.linalg  # noqa: F401 (loads SciPy's own OpenBLAS)
    parts = [_state, f'numpy {np.__version__}']
    try:
        from threadpoolctl import threadpool_info
        parts += sorted(f'{i.get("internal_api")} {i.get("version")} {i.get("architecture")}'
                        for i in threadpool_info() if i.get('user_api') == 'blas')
    except ImportError:     # scikit-learn's installs bring it
        parts.append('blas unknown')
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
        parts += [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]
    except ImportError:     # NumPy 1.x keeps them elsewhere
        parts.append('dispatch unknown')
    return '; '.join(parts)
