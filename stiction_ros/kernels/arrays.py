"""Array types of the kernels' signatures, for the type checker (numba ignores them)."""

import numpy as np
from numpy.typing import NDArray

# float64 arrays: signals, states, parameter vectors, matrices.
Floats = NDArray[np.float64]
# int64 arrays: segment starts and stops, sample indices.
Ints = NDArray[np.int64]
# uint8 arrays: raw bytes (MCAP chunks).
Bytes = NDArray[np.uint8]
