"""``drivemap draft DOCUMENT``: a map drafted from the register tables of a manual.

readers (one per format) -> :mod:`.tables` (the common table model) -> :mod:`.columns` (header and
column recognition) -> :mod:`.cells` / :mod:`.units` (cell parsers) -> :mod:`.rows` (registers) ->
:mod:`.writer` (the map text, checked in memory by the real compiler) -> :mod:`.summary`.
Nothing the document does not state is written: it is listed for review instead.
"""

from __future__ import annotations

__all__: list[str] = []
