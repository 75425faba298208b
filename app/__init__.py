"""The sonarcal browser workbench: a viser shell over calib_core.

``app.state`` holds the session, detections, undo and change records (pure Python,
no viser); ``app.server`` wires the panels (one module each) to a shared
:class:`viser.ViserServer`.
"""
