"""The knowledge-base service."""

from importlib.metadata import version

__version__ = version("cpkb")
