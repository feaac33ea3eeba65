"""The package version (a leaf: imported by result writers without a cycle)."""

__version__ = "0.1.0"
