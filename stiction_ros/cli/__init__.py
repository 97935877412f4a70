"""Command-line entry points (no rclpy needed)."""
