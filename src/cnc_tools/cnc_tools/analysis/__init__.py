"""Analysis of a run record: scoring, metrics, circular test, plots (no rclpy, no rosbags)."""
