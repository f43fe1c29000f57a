"""The package's version, below every layer so that any of them can record it."""

__version__ = "0.1.0"
