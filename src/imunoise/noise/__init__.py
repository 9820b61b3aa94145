"""The modelling core: noise processes, their sums, and the estimators that fit them to IMU data.

Part of the data path IMU → detection → modelling → filter: it turns static (or pooled) IMU data into error
models, and imports only :mod:`imunoise.io`, :mod:`imunoise.errors`, :mod:`imunoise.units` and itself.

* processes and their algebra: :mod:`~imunoise.noise.processes` (the registry), ``process_*`` (one module per
  process: WV closed form, simulation, state-space block, continuous equivalents), :mod:`~imunoise.noise.model`
  (sums of processes, ``2 * AR1() + WN() + RW()``), :mod:`~imunoise.noise.state_space`;
* the Haar wavelet variance: :mod:`~imunoise.noise.wv` (pooled segments), :mod:`~imunoise.noise.wv_stream` (a
  long series in chunks), :mod:`~imunoise.noise.wv_log` (logs longer than memory);
* estimators: :mod:`~imunoise.noise.estimator` (GMWM, on :mod:`~imunoise.noise.fitting`),
  :mod:`~imunoise.noise.selection` (WVIC / GOF over sub-models), the baselines :mod:`~imunoise.noise.allan`
  (IEEE 952) and :mod:`~imunoise.noise.em` (EM with a Kalman E-step);
* what is built on fits: :mod:`~imunoise.noise.equivalent_noise` (the (N, K) pair and filter noise),
  :mod:`~imunoise.noise.imu_model` (the model files), :mod:`~imunoise.noise.plots`.

The modules stood at the package root before this folder existed; :mod:`~imunoise.noise.moved` keeps those
import paths working, with a deprecation warning, for one release.
"""
