"""Choosing between candidate detections across a session (image side, sonar side)."""
