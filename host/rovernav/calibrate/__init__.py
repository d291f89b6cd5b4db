"""Calibration from what the camera sees: `rovernav calibrate camera` (rovernav.calibrate.camera)."""
