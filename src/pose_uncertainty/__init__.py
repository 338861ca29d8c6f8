"""Pose uncertainty of a differential-drive robot on noisy wheel odometry.

Three ways to the same question — how sure is the robot of its pose after
driving a path — computed side by side:

* :mod:`pose_uncertainty.methods.covariance` — first-order covariance propagation
  (Siegwart & Nourbakhsh) and its error ellipses;
* :mod:`pose_uncertainty.methods.maps` — probability maps from the velocity and
  odometry motion models (Thrun, Burgard & Fox);
* :mod:`pose_uncertainty.methods.sampling` — Monte Carlo ground truth.

Trajectories are built with :mod:`pose_uncertainty.core.trajectories`; the
kinematics live in :mod:`pose_uncertainty.core.kinematics`.
"""

#: The package version: the one place it is written (pyproject.toml reads it from here).
__version__ = "0.1.0"

__all__ = ["__version__"]
