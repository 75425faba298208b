"""Sphere detection in images (:mod:`.image`) and sonar clouds (:mod:`.sonar`).

Both detectors return the small result types of :mod:`.types`.
"""
