"""Stereo transforms between cameras: chained covariances, and cameras vouching for each other."""
