"""Field data in: ROS 1 / ROS 2 bags and video + scan times -> a session folder, with target-motion checks."""
