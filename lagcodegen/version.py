"""The version of lagcodegen (one place; recorded in generated files and cache keys)."""

__version__ = "0.1.0"
