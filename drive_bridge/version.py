"""The version of drive-bridge (pyproject.toml's ``version``, which must match)."""

__version__ = "0.1.0"
