"""The ``scanalign`` command line (:mod:`.main`) and its config files (:mod:`.config`)."""

from scanalign.cli.commands import main

__all__ = ["main"]
