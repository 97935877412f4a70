"""Simulated corpora of closed control loops, for training and testing detectors."""
