"""The paper's experiments (docs/guide/theory.rst, 'Experiments'): scenarios, method configurations, runs over seeds and
outage windows, tables and figures (:mod:`~imunoise.experiments.common`, :mod:`~imunoise.experiments.online_exp`,
:mod:`~imunoise.experiments.denial`, :mod:`~imunoise.experiments.report`, :mod:`~imunoise.experiments.plots`).

Top of the stack: it may import every stage of the data path IMU → detection → modelling → filter (io,
detect, the modelling modules, nav, online) and :mod:`imunoise.sim`; only the CLI (``imunoise experiment``,
``imunoise demo``) imports it.
"""
