"""Real robots and recorded data (paper sec. IV-E): map a recording (ROS 1 / ROS 2 bag, MCAP, TUM RGB-D
folder) into the episode layout (:mod:`activesplat.robot.mapping`), read without a ROS install
(:mod:`activesplat.robot.recording`)."""
