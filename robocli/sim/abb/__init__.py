"""The built-in ABB simulator: the ROS-Industrial robot-side server's protocol sessions
(:mod:`.session`) and the server on the motion and state ports (:mod:`.server`)."""
