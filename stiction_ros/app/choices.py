"""The analyzer's option values, in a module light enough for ``--help`` to import."""

MODEL_CHOICES = ('kano', 'choudhury', 'both')
LOOP_TYPES = ('auto', 'self-regulating', 'integrating')
# The readers' orders of day and month (stiction_ros.analysis.readers.stamps.DATE_ORDERS).
DATE_ORDERS = ('dmy', 'mdy')
