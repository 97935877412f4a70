"""
The one place numba is imported; kernels compile on first use, or come ready-built.

Every compiled loop of the package is decorated with this module's
``njit``.  Importing a kernel module costs nothing: numba itself (about 0.4 s
to import and 0.3 s to set up its typing on the project's machine, more than
a whole analysis of a day's record) loads only when a kernel is first called.

Kernels declared with ``aot=SIGNATURE`` are also built ahead of time into
one extension module (:func:`build_ahead_of_time`, run by
``stiction-precompile``).  A call of such a kernel whose arguments match the
signature exactly runs the built code without loading numba at all; any
other call, and every kernel without ``aot``, loads numba and its cached
compilation.  Both are compiled by numba from the same source, so they give
the same bits (test/test_ahead_of_time.py).  The built module is used only
while its recorded hash of the kernel sources and the numba version match;
otherwise it is ignored.  Once numba is loaded every kernel runs through
it, so threads get the GIL-free versions (``nogil``).

Without numba (it is in the requirements, so only on a broken install) the
functions run as plain Python, slowly but with the same results.  For the
type checker ``njit`` returns the function it decorates unchanged.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import json
import os
import sys
import threading
from types import ModuleType
from typing import Any, Callable, overload, TYPE_CHECKING, TypeVar

F = TypeVar('F', bound=Callable[..., Any])

# The ahead-of-time module and its manifest, beside this file.
AOT_MODULE = 'stiction_ros._kernels_aot'
AOT_MANIFEST = os.path.join(os.path.dirname(__file__), '_kernels_aot.json')
KERNEL_DIR = os.path.join(os.path.dirname(__file__), 'kernels')
# Set (to anything) to ignore the built kernels: every kernel then runs through numba.
JIT_ONLY = 'STICTION_ROS_JIT_ONLY'

_lock = threading.RLock()
_kernels: list[Kernel] = []
_aot_functions: list[tuple[Callable[..., Any], str]] = []
_numba: ModuleType | None = None
_aot: ModuleType | None = None
_aot_looked = False


def sources_hash() -> str:
    """Return a hash of every kernel source file (what the built module was compiled from)."""
    digest = hashlib.sha256()
    for name in sorted(os.listdir(KERNEL_DIR)):
        if name.endswith('.py'):
            with open(os.path.join(KERNEL_DIR, name), 'rb') as f:
                digest.update(name.encode() + b'\0' + f.read())
    return digest.hexdigest()


def export_name(function: Callable[..., Any]) -> str:
    """Return the name a kernel has in the ahead-of-time module."""
    return f'{function.__module__.rsplit(".", 1)[-1]}__{function.__name__}'


def ahead_of_time_status() -> str:
    """Return ``'fresh'``, or why the built kernels would not be used."""
    if os.environ.get(JIT_ONLY):
        return f'{JIT_ONLY} is set'
    try:
        with open(AOT_MANIFEST, encoding='utf-8') as f:
            manifest = json.load(f)
    except (OSError, ValueError):
        return 'not built (stiction-precompile builds it)'
    if manifest.get('sources') != sources_hash():
        return 'stale: a kernel source changed since it was built (run stiction-precompile)'
    return 'fresh'


def _load_aot() -> ModuleType | None:
    global _aot, _aot_looked
    with _lock:
        if not _aot_looked:
            _aot_looked = True
            if ahead_of_time_status() == 'fresh':
                try:
                    _aot = importlib.import_module(AOT_MODULE)
                except ImportError:
                    pass
    return _aot


def _check(code: str) -> Callable[[Any], bool]:
    """Return a test of one argument against one type of an ``aot`` signature."""
    import numpy as np
    code = code.replace(' ', '')
    if code.endswith(']'):
        dtype = np.dtype({'f8': np.float64, 'i8': np.int64, 'b1': np.bool_}[code[:2]])
        ndim = code.count(',') + 1

        def array_ok(a: Any) -> bool:
            # The built code reads the memory as the signature says: anything
            # else (float32, a strided view) would be read wrongly, not refused.
            return (type(a) is np.ndarray and a.dtype == dtype and a.ndim == ndim
                    and a.flags.c_contiguous)
        return array_ok
    kinds = {'f8': (float, int, np.floating, np.integer), 'i8': (int, np.integer),
             'b1': (bool, np.bool_)}[code]
    exact_bool = code == 'b1'
    return lambda x: isinstance(x, kinds) and (exact_bool or not isinstance(x, bool))


def arguments(signature: str) -> list[str]:
    """Return the argument types of a signature such as ``'f8[:, ::1](i8, f8[::1])'``."""
    depth = 0
    for i in range(len(signature) - 1, -1, -1):
        depth += {')': 1, '(': -1}.get(signature[i], 0)
        if depth == 0:
            break
    parts, depth, start = [], 0, i + 1
    inner = signature[:-1]
    for j in range(start, len(inner)):
        depth += {'[': 1, '(': 1, ']': -1, ')': -1}.get(inner[j], 0)
        if inner[j] == ',' and depth == 0:
            parts.append(inner[start:j])
            start = j + 1
    parts.append(inner[start:])
    return [p.strip() for p in parts if p.strip()]


class Kernel:
    """A kernel that compiles on its first call (see the module's description)."""

    def __init__(self, function: Callable[..., Any], options: dict[str, Any],
                 aot: str | None) -> None:
        self.py_func = function
        self.options = options
        self.aot = aot
        self.dispatcher: Any = None
        self._built: Callable[..., Any] | None = None
        self._checks: list[Callable[[Any], bool]] | None = None
        functools.update_wrapper(self, function)

    def __call__(self, *args: Any) -> Any:
        """Run the kernel: built ahead of time when the arguments fit, else by numba."""
        if self.dispatcher is not None:
            return self.dispatcher(*args)
        if self.aot is not None and _numba is None:
            built = self._ahead_of_time()
            if built is not None and self._fits(args):
                return built(*args)
        return _load_numba(self)(*args)

    def _ahead_of_time(self) -> Callable[..., Any] | None:
        if self._built is None:
            module = _load_aot()
            self._built = getattr(module, export_name(self.py_func), None) if module else None
            if self._built is not None and self.aot is not None:
                self._checks = [_check(c) for c in arguments(self.aot)]
        return self._built

    def _fits(self, args: tuple[Any, ...]) -> bool:
        checks = self._checks or []
        return len(args) == len(checks) and all(ok(a) for ok, a in zip(checks, args))


def _load_numba(kernel: Kernel) -> Any:
    """Load numba, make every kernel a numba dispatcher; return ``kernel``'s."""
    global _numba
    with _lock:
        if _numba is None:
            try:
                import numba
            except ImportError:  # pragma: no cover - numba is in the requirements
                for k in _kernels:
                    k.dispatcher = k.py_func
                return kernel.dispatcher
            for k in _kernels:
                k.dispatcher = numba.njit(**k.options)(k.py_func)
            # Compiled code finds the kernels it calls among its module's globals:
            # they must be numba's dispatchers before anything compiles.
            swap = {id(k): k.dispatcher for k in _kernels}
            for name, module in list(sys.modules.items()):
                if name.startswith('stiction_ros') and module is not None:
                    space = vars(module)
                    for attr, value in list(space.items()):
                        if isinstance(value, Kernel) and id(value) in swap:
                            space[attr] = swap[id(value)]
            _numba = numba
    return kernel.dispatcher


def load_numba() -> None:
    """Switch every kernel to numba's compilation now (threads need its GIL-free code)."""
    if _numba is None and _kernels:
        _load_numba(_kernels[0])


def _decorate(function: Callable[..., Any], options: dict[str, Any], aot: str | None) -> Any:
    with _lock:
        if aot is not None:
            # Recorded whenever the module is imported, before numba loads or after:
            # stiction-precompile imports some kernel modules only once numba is in.
            _aot_functions.append((function, aot))
        if _numba is not None:
            return _numba.njit(**options)(function)
        kernel = Kernel(function, options, aot)
        _kernels.append(kernel)
        return kernel


def ahead_of_time_functions() -> list[tuple[Callable[..., Any], str]]:
    """Return (function, signature) of every kernel declared with ``aot`` imported so far."""
    return list({export_name(fn): (fn, sig) for fn, sig in _aot_functions}.values())


def build_ahead_of_time(output_dir: str | None = None) -> list[str]:
    """
    Build the ``aot`` kernels of the imported kernel modules into one extension module.

    The caller imports every kernel module first.  Returns the names built.
    Raises whatever numba's ahead-of-time compiler raises (no C compiler, for
    one); the kernels then stay just-in-time.
    """
    functions = ahead_of_time_functions()
    # numba compiles a kernel's callees from its module's globals: dispatchers.
    load_numba()
    from numba.pycc import CC
    output_dir = output_dir or os.path.dirname(__file__)
    cc = CC(AOT_MODULE.rsplit('.', 1)[-1])
    cc.output_dir = output_dir
    cc.verbose = False
    for function, signature in functions:
        cc.export(export_name(function), signature)(function)
    # The manifest goes last, and only after a good build: a failed build
    # leaves no manifest that would vouch for an old module.
    manifest = os.path.join(output_dir, os.path.basename(AOT_MANIFEST))
    if os.path.exists(manifest):
        os.remove(manifest)
    cc.compile()
    with open(manifest, 'w', encoding='utf-8') as f:
        json.dump({'sources': sources_hash(), 'numba': getattr(_numba, '__version__', ''),
                   'kernels': [export_name(fn) for fn, _ in functions]}, f, indent=1)
    return [export_name(fn) for fn, _ in functions]


if TYPE_CHECKING:
    @overload
    def njit(function: F, /) -> F: ...

    @overload
    def njit(*, cache: bool = ..., nogil: bool = ..., inline: str = ...,
             aot: str | None = ..., **options: Any) -> Callable[[F], F]: ...

    def njit(*args: Any, **kwargs: Any) -> Any:
        """Compile a function, or return a decorator that does (numba's njit)."""
else:
    def njit(*args, aot=None, **options):
        """Return a :class:`Kernel` of the function (a decorator when called with options)."""
        if args and callable(args[0]):
            return _decorate(args[0], options, aot)
        return lambda function: _decorate(function, options, aot)

__all__ = ['ahead_of_time_status', 'arguments', 'build_ahead_of_time', 'Kernel', 'load_numba',
           'njit', 'sources_hash']
