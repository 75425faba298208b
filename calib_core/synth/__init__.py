"""Synthetic sessions with exact ground truth (physics by ray casting, not drawings).

- :mod:`scene`: primitives (mesh target, spheres, discs, capsules, cylinders, boxes, planes,
  groups) and the one ray caster :func:`scene.raycast` shared by camera and sonar.
- :mod:`camera_render`: per-pixel rays through the real lens model, edge supersampling,
  turbidity, blur, noise.
- :mod:`sonar_sim`: BlueView BV5000-2250-like pan scan (first strong return per 1 deg cone).
- :mod:`rig`, :mod:`world`: random intrinsics, rig, placements and scene content.
- :mod:`presets`, :mod:`generate`, :mod:`ground_truth`: ``generate_session(out_dir, preset,
  seed)`` writes a session plus ``ground_truth.yaml``; ``load_ground_truth(root)`` reads it.
"""
