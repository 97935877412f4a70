"""
Every error the package raises on purpose, under one base class.

Catch :class:`StictionError` for "the input or the configuration is wrong,
and the message says how": anything else escaping the package is a bug.
Each class also derives from the built-in exception it was before the
hierarchy existed (``ValueError`` for bad values, ``OSError`` for files),
so code that caught those still works.  The classes live here, and the
modules that raise them import them from here.
"""


class StictionError(Exception):
    """Base of every error stiction_ros raises on purpose; its message names the fix."""


# Layer kernels, models, bag ---------------------------------------------------------------

class ModelError(StictionError, ValueError):
    """A model parameter or input is invalid; the message says which and why."""


class BagError(StictionError, OSError):
    """A bag cannot be written or read; the message names the path and the cause."""


class BagReadError(StictionError, ValueError):
    """The input is not a readable bag; the message names the file and the problem."""


class DefinitionNotFound(StictionError, LookupError):
    """No ``.msg`` file for a type is installed where we looked."""


# Layer sim ---------------------------------------------------------------------------------

class ConfigError(StictionError, ValueError):
    """A loop description is invalid; the message names the key and the fix."""


class PlantError(StictionError, ValueError):
    """The plant description is invalid; the message names the field and the fix."""


class SourceError(StictionError, ValueError):
    """A source description is invalid; the message names the key and the fix."""


# Layer analysis ----------------------------------------------------------------------------

class InputError(StictionError, ValueError):
    """The input cannot be analysed; a one-line message names the file and the problem."""

    def __init__(self, message: object) -> None:
        super().__init__(' '.join(str(message).splitlines()))


class GridError(StictionError, ValueError):
    """The stamps do not define a sample grid (fewer than two distinct stamps)."""


class ReportWriteError(StictionError, OSError):
    """A report cannot be written; the message names the report, the path and the cause."""


class IdentifyError(StictionError, ValueError):
    """The data cannot support identification (too short, no MV, flat OP)."""


class DetectorFileError(StictionError):
    """The detector's model file is missing, damaged or of another version."""


class TrainingSetError(StictionError, ValueError):
    """A simulated set keeps too few records of a label to train or calibrate on."""


# Layers nodes and cli ----------------------------------------------------------------------

class StateFileError(StictionError, ValueError):
    """The saved state cannot be used; the message says why."""


class StartupError(StictionError, RuntimeError):
    """The node cannot start with the parameters it was given; the message says why."""


class LoopError(StictionError, RuntimeError):
    """The loop could not run; the message says which node and why."""
