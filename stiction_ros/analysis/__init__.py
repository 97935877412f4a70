"""
Offline analysis of loop recordings: is the valve sticking, how much, and how well do models fit.

Plain numpy/scipy; nothing here imports rclpy, so the analyzer runs anywhere.
"""
