"""File formats: point clouds, images, intrinsics, atomic writes."""
