"""Bag I/O: MCAP bags in the rosbag2 layout written and read back, salvage, replay timing, synthetic runs."""
