"""cellrunner: run Universal Robots production cells from YAML."""

__version__ = "0.1.0"
