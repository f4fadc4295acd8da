"""Paper 002's disturbance paths, ROS-free: design (PDC, DOB, MBDA), per-sample filters, the linear loop, the report."""
