"""The package version, the one source (``pyproject.toml`` reads it; ``fluidem.__version__``,
``fluidem --version``, ``run.json`` and checkpoints report it)."""

__all__ = ["__version__"]

__version__ = "0.1.0.dev0"
