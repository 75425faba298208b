"""Finding the sphere in a camera image: candidates (votes, discs, regions, Hough), the cone fit on
the outline, the sonar-guided look, the score. Entry point: :func:`.detect.detect_sphere_in_image`."""
