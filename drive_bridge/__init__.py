"""drive-bridge: commission the servo axes of a Cartesian robot over CANopen."""

__version__ = "0.1.0"
