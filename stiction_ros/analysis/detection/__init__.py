"""
Stiction detection from OP, PV and SP: judge, measure, decide.

Layers, each importing only those before it: :mod:`resolve` (can the record
be judged; the period sanity rule), :mod:`stale` and :mod:`interpolated`
(historian holds and interpolated rows), :mod:`stuck` (stuck periods and
slips), :mod:`output_error` and
:mod:`prediction_error` (two fits of a sticky valve), :mod:`model_file`
(plain-array files, read without pickle), :mod:`cnn` (the networks, run in
NumPy), :mod:`features` (the scale-free feature vector), :mod:`stack` (the
large network weighed in) and :mod:`detect` (the three answers with
probability and evidence).  :mod:`dataset`, :mod:`deadband_like`,
:mod:`train` and :mod:`cnn_train` only rebuild the files (``make detector``,
``make cnn``) and need scikit-learn or PyTorch; :mod:`stack` reaches
:mod:`dataset` only to key its cache of simulated records' logits.
"""

from stiction_ros.analysis.detection.detect import ANSWERS, BAND, detect, Detection, \
    load_model, probability_text
from stiction_ros.analysis.detection.features import extract, FEATURE_NAMES
from stiction_ros.analysis.detection.model_file import DetectorFileError
from stiction_ros.analysis.detection.resolve import Judgeable, judgeable, period_sanity

__all__ = ['ANSWERS', 'BAND', 'detect', 'Detection', 'DetectorFileError', 'extract',
           'FEATURE_NAMES', 'judgeable', 'Judgeable', 'load_model', 'period_sanity',
           'probability_text']
