"""Localization: worlds, sensors and the three Bayes filters (EKF, histogram, particle)."""
