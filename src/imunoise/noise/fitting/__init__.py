"""GMWM machinery behind :mod:`imunoise.noise.estimator` and :mod:`imunoise.noise.selection` (paper Eq. 6,
docs/guide/theory.rst, 'GMWM estimator'–5).

One concept per module:

* :mod:`~imunoise.noise.fitting.arguments` — checks of the sample rate and data unit shared by every estimator;
* :mod:`~imunoise.noise.fitting.params` — the unconstrained parametrisation u ↔ θ, its bounds and kind codes;
* :mod:`~imunoise.noise.fitting.kernels` — numba closed forms: model WV, Jacobian, objective, Levenberg–Marquardt;
* :mod:`~imunoise.noise.fitting.problem` — :class:`GMWMProblem` (WV, Ω, normalisation), guided starts, Cov(û);
* :mod:`~imunoise.noise.fitting.result` — :class:`GMWMFit` and its single factory :meth:`GMWMFit.from_problem`;
* :mod:`~imunoise.noise.fitting.estimate` — the estimators :func:`gmwm` and :func:`refit` and their solver;
* :mod:`~imunoise.noise.fitting.wvic` — the WVIC criterion of the model selection (:mod:`imunoise.noise.selection`);
* :mod:`~imunoise.noise.fitting.candidates`, :mod:`~imunoise.noise.fitting.candidate_fit`,
  :mod:`~imunoise.noise.fitting.ranking` —
  the selection's candidate structures, the fit of one from its sub-models, and :class:`ModelRanking`;
* :mod:`~imunoise.noise.fitting.warm` — :func:`warm_up`: compile or load the kernels before the first fit.

The documented import path stays :mod:`imunoise.noise.estimator` (and ``imunoise.gmwm`` etc.). Part of the
modelling stage of the data path (IMU → detection → modelling → filter): it imports the model algebra
(:mod:`imunoise.noise.model`, :mod:`imunoise.noise.processes`), :mod:`imunoise.noise.wv`, :mod:`imunoise.units` and
:mod:`imunoise.errors`, never detection, navigation or I/O.
"""

from imunoise.noise.fitting.warm import warm_up

__all__ = ["warm_up"]
