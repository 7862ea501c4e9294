"""Tuning the drive's cascade from the identified model: design, experiment, validation."""
