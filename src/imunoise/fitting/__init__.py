"""GMWM machinery behind :mod:`imunoise.estimator` and :mod:`imunoise.selection` (paper Eq. 6,
docs/guide/theory.rst, 'GMWM estimator'–5).

One concept per module:

* :mod:`~imunoise.fitting.arguments` — checks of the sample rate and data unit shared by every estimator;
* :mod:`~imunoise.fitting.params` — the unconstrained parametrisation u ↔ θ, its bounds and kind codes;
* :mod:`~imunoise.fitting.kernels` — numba closed forms: model WV, Jacobian, objective, Levenberg–Marquardt;
* :mod:`~imunoise.fitting.problem` — :class:`GMWMProblem` (WV, Ω, normalisation), guided starts, Cov(û);
* :mod:`~imunoise.fitting.result` — :class:`GMWMFit` and its single factory :meth:`GMWMFit.from_problem`;
* :mod:`~imunoise.fitting.estimate` — the estimators :func:`gmwm` and :func:`refit` and their solver;
* :mod:`~imunoise.fitting.wvic` — the WVIC criterion of the model selection (:mod:`imunoise.selection`);
* :mod:`~imunoise.fitting.candidates`, :mod:`~imunoise.fitting.candidate_fit`, :mod:`~imunoise.fitting.ranking` —
  the selection's candidate structures, the fit of one from its sub-models, and :class:`ModelRanking`;
* :mod:`~imunoise.fitting.warm` — :func:`warm_up`: compile or load the kernels before the first fit.

The documented import path stays :mod:`imunoise.estimator` (and ``imunoise.gmwm`` etc.). Part of the
modelling stage of the data path (IMU → detection → modelling → filter): it imports the model algebra
(:mod:`imunoise.model`, :mod:`imunoise.processes`), :mod:`imunoise.wv`, :mod:`imunoise.units` and
:mod:`imunoise.errors`, never detection, navigation or I/O.
"""

from imunoise.fitting.warm import warm_up

__all__ = ["warm_up"]
