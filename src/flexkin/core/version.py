"""flexkin's version: the one place it is written (``pyproject.toml`` reads it from here, the
package re-exports it, and the on-disk caches key their entries with it)."""

__version__ = "0.2.0"
