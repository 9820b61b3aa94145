"""Measurements of the filter (docs/guide/theory.rst, 'Navigation filter'): the aiding half of the last stage of the
data path (IMU → detection → modelling → filter); one filter step, pluggable measurements.

A measurement is a pair of plain numba functions: one builds the innovation, its Jacobian and noise for the
current state, ``dz, H, R = <name>(nav, n, ...)`` (δz = ẑ − z with the error convention δx = x̂ − x of
:mod:`imunoise.nav.ekf`, so ``dz ≈ H δx``), and an optional gate that says whether it applies now. Both the
filter engine (:func:`imunoise.nav.filter_loop.run_steps`, through :func:`imunoise.nav.streams.measure`) and
the step filter (:class:`~imunoise.nav.ekf.LooselyCoupledEKF`) call these functions and the one update
:func:`imunoise.nav.ekf_kernels.kf_update` (Joseph form, χ² gate; it returns the innovation covariance S and
the gain K as filterpy's ``KalmanFilter.update`` keeps them).

========================  ==========================================================================
:mod:`.gnss_position`     antenna position fix (lever arm, referred to the filter epoch with v̂)
:mod:`.zupt`              zero velocity (ZUPT) and zero angular rate (ZARU) at stops
:mod:`.nhc`               non-holonomic constraints: zero lateral and vertical body velocity while driving
:mod:`.gnss_velocity`     antenna velocity (v + C_b^n (ω × l))
:mod:`.odometer`          vehicle forward speed (wheel odometer; scale-factor error as speed-proportional noise)
========================  ==========================================================================

Adding one: a module here with its ``dz, H, R`` function (and gate), its kind in
:mod:`imunoise.nav.streams` (a name in ``KINDS`` and a branch in ``measure``); every path into the filter then
takes it as a stream; ``tests/nav/test_nav_measurements.py`` checks every H against a numerical
Jacobian.
"""
