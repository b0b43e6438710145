"""Shared foundations of every area: argument checks at the API boundary (:mod:`.arrays`),
rigid transforms (:mod:`.rigid`) and the settings schema of the C++ structs (:mod:`.settings`).

Mirrors ``_core.common`` and ``cpp/include/scanalign/common/``. Imports nothing else of the package.
"""
