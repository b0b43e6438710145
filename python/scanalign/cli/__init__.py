"""The ``scanalign`` command line (:mod:`.commands`) and its settings options (:mod:`.settings`)."""

from scanalign.cli.commands import main

__all__ = ["main"]
