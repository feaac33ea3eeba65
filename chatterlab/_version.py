"""The package version (a leaf: imported by result writers without a cycle)."""

__version__ = "0.3.0"
