"""``igserver quality weather``: error against run time of the weather (docs/design.md#quality).

The particle part (rain and snow: particle count and cube size against a dense reference) lives in
quality/precipitation.py (a library module, so the combined ``igserver quality`` runs it once, here);
the fog part (against a multiple-scattering reference) joins here.

Usage: igserver quality weather [options of quality/precipitation.py: --scene --size --frames --drops
       --tiles --quick --out]
"""

from __future__ import annotations

from . import precipitation


def run(argv: list[str]) -> int:
    return precipitation.main(argv)


def study(quick: bool = False):
    """The combined report's points (igserver quality)."""
    return precipitation.study(quick)
