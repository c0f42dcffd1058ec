"""The ``hexapod-pin`` command line: commands only, over library functions."""

from .main import app

__all__ = ["app"]
