"""Simulated range sensors (LiDAR, RGB-D, held-out sensors) and their scenes."""
