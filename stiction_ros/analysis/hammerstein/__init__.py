"""
Quantify valve stiction (S, J) from OP and PV alone, with a Hammerstein model.

An industrial record seldom has the valve position, so the valve is modelled
inside the loop (Srinivasan et al. 2005; Jelali 2008)::

    OP --> Kano model (S, J) --> MV_hat --> linear plant G(q) --> PV

The modules, each importing only those listed after it:

* ``quantify``: :func:`quantify`, its :class:`HammersteinResult` and the
  checks that mark a result unreliable (evidence, identifiability);
* ``stats``: effective sample size, delete-a-block jackknife, intervals and
  the JSON form of G;
* ``search``: the coarse-to-fine search of (S, J), dead time and the valve's
  start states;
* ``problem``: :class:`HammersteinProblem`, the data and the separable ARX
  regression (a :class:`stiction_ros.analysis.fit_core.Problem`).

The compiled kernels live in ``stiction_ros.kernels.hammerstein``.

References
----------
Jelali, M. (2008), Estimation of valve stiction in control loops using
separable least-squares and global search algorithms, Journal of Process
Control 18(7-8), 632-642.
Srinivasan, R., Rengaswamy, R., Narasimhan, S., Miller, R. (2005), Control
loop performance assessment. 2. Hammerstein model approach for stiction
diagnosis, Industrial & Engineering Chemistry Research 44(17), 6719-6728.
Kano, M., Maruta, H., Kugemoto, H., Shimizu, K. (2004), Practical model and
detection algorithm for valve stiction, IFAC DYCOPS 2004, Cambridge MA.

"""

from stiction_ros.analysis.hammerstein.estimate import DEFAULT_MAX_DELAY, HammersteinResult, \
    MAX_IMPROVEMENT_RATIO, quantify, REFERENCE
from stiction_ros.analysis.hammerstein.problem import HammersteinProblem, MIN_ROWS, \
    valid_segments
from stiction_ros.analysis.hammerstein.search import Search
from stiction_ros.analysis.hammerstein.stats import effective_samples, jackknife, \
    linear_model_json
from stiction_ros.kernels.hammerstein import segment_path

__all__ = [
    'DEFAULT_MAX_DELAY', 'effective_samples', 'HammersteinProblem', 'HammersteinResult',
    'jackknife', 'linear_model_json', 'MAX_IMPROVEMENT_RATIO', 'MIN_ROWS', 'quantify',
    'REFERENCE', 'Search', 'segment_path', 'valid_segments',
]
