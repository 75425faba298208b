"""Finding the sphere in a range cloud (sonar, LiDAR, RGB-D): search, fit, beam width, outline.
Entry point: :func:`.detect.detect_sphere_in_cloud`."""
