"""
Stiction detection from OP, PV and SP: judge, measure, decide.

Layers, each importing only those before it: :mod:`resolve` (can the record
be judged; the period sanity rule), :mod:`stuck` (stuck periods and slips),
:mod:`features` (the scale-free feature vector),
:mod:`model_file` (the shipped tree model, read without pickle) and
:mod:`detect` (the three answers with probability and evidence).
:mod:`train` is used only to rebuild the model file and needs scikit-learn.
"""

from stiction_ros.analysis.detection.detect import ANSWERS, detect, Detection, load_model, \
    probability_text
from stiction_ros.analysis.detection.features import extract, FEATURE_NAMES
from stiction_ros.analysis.detection.model_file import DetectorFileError
from stiction_ros.analysis.detection.resolve import Judgeable, judgeable, period_sanity

__all__ = ['ANSWERS', 'detect', 'Detection', 'DetectorFileError', 'extract', 'FEATURE_NAMES',
           'judgeable', 'Judgeable', 'load_model', 'period_sanity', 'probability_text']
