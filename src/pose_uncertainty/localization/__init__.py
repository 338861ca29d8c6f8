"""Localization: the three methods as the prediction steps of three Bayes filters, with sensors.

Covariance propagation → the (extended) Kalman filter (:mod:`.ekf`); probability maps →
the histogram filter (:mod:`.histogram`); Monte Carlo → the particle filter (:mod:`.particle`,
resampling schemes in :mod:`.resampling`). They run on the same simulated data
(:mod:`.simulate`) in a world of landmarks and walls (:mod:`.world`) seen by a range–bearing
sensor or a laser's beam model (:mod:`.sensors`; unmapped obstacles and the distance filter in
:mod:`.dynamic`, scan-to-map matching as a pose measurement in :mod:`.scan_matching`), and are measured
against the true
path (:mod:`.measures`). Every filter run returns a :class:`.result.FilterResult`
(per step: estimate, covariance, region coverage, compute time, diagnostics) and can
stream its full state (particles, grid) to an ``on_step`` callback.

>>> import numpy as np
>>> from pose_uncertainty.core import trajectories as tr
>>> from pose_uncertainty.localization import ekf, particle, sensors, simulate, world
>>> w = world.World(np.array([[2.0, 1.0], [0.0, 3.0], [4.0, -1.0]]), np.arange(3))
>>> sen = sensors.RangeBearingSensor(range_std=0.1, bearing_std=0.05, period=0.5)
>>> run = simulate.simulate(tr.straight(2.0, speed=0.5, dt=0.1), w, np.random.default_rng(1),
...                         k_r=1e-3, k_l=1e-3, landmark_sensor=sen)
>>> e = ekf.run_ekf(run, w, sen)
>>> p = particle.run_particle(run, w, sen, np.random.default_rng(2))
>>> e.mean.shape, p.cov.shape
((41, 3), (41, 3, 3))
"""
