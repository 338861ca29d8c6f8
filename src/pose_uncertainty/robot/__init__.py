"""Your robot: from a ROS bag to calibrated error constants and navigation-stack parameters.

An application of the analysis layer to a real robot's logs, read without ROS
installed (the ``rosbags`` library). One module per step:

* :mod:`.config` — the robot file (wheel radii, track, encoder, joint and topic names);
* :mod:`.messages` — the ROS message types this package reads and writes;
* :mod:`.bag` — reading a rosbag2 folder, a bare ``.mcap`` or a ROS 1 ``.bag``;
* :mod:`.align` — cleaning the streams and aligning them in time (SE(2) interpolation);
* :mod:`.segments` — the path cut into independent segments, their odometry and residuals;
* :mod:`.geometry_fit` — wheel radii and track (E_d, E_b of Borenstein & Feng 1996);
* :mod:`.noise_fit` — the wheel error constants ``k_r, k_l`` (Method A) and held-out checks;
* :mod:`.laps` — UMBmark squares found in a recording and fed to :mod:`..analysis.umbmark`;
* :mod:`.nav2` — nav2 AMCL's differential motion model and its alphas fitted to the wheel model;
* :mod:`.nav2_omni` — nav2 AMCL's omni motion model and its alphas fitted to an omni drive's wheel model;
* :mod:`.horizon` — distance and time until the 95 % position error reaches a threshold;
* :mod:`.exports` — ``ros2_control.yaml``, ``nav2_amcl.yaml``, ``robot_localization.yaml``;
* :mod:`.simulated` — a simulated robot's parameters (known truth) and its commanded drive;
* :mod:`.simulate` — that robot simulated and written as a bag (for tests and the pipeline);
* :mod:`.run_bag` — a run log of this project exported as a ROS 2 bag;
* :mod:`.calibrate` — the whole procedure, writing the outputs of ``robot calibrate``.

This layer imports ``core``, ``methods`` and ``analysis``; none of them imports it.
"""
