"""
The one place numba is imported.

Every compiled loop of the package is decorated with this module's
``njit``; without numba (it is in the requirements, so only on a broken
install) the same functions run as plain Python, slowly but with the same
results.  For the type checker ``njit`` returns the function it decorates
unchanged, so a kernel keeps its annotated signature (numba itself ignores
annotations: it compiles for the types it is called with).
"""

from typing import Any, Callable, overload, TYPE_CHECKING, TypeVar

F = TypeVar('F', bound=Callable[..., Any])

if TYPE_CHECKING:
    @overload
    def njit(function: F, /) -> F: ...

    @overload
    def njit(*, cache: bool = ..., nogil: bool = ..., inline: str = ...,
             **options: Any) -> Callable[[F], F]: ...

    def njit(*args: Any, **kwargs: Any) -> Any:
        """Compile a function, or return a decorator that does (numba's njit)."""
else:
    try:
        from numba import njit
    except ImportError:  # pragma: no cover - numba is in the requirements
        def njit(*args: Any, **kwargs: Any) -> Any:
            """Return the function unchanged when numba is missing."""
            if args and callable(args[0]):
                return args[0]
            return lambda f: f

__all__ = ['njit']
