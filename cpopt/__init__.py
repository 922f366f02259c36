"""cpopt: motion planning for three-link planar robots with a passive third joint under gravity."""

__version__ = "0.1.0"
