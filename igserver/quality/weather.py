"""``igserver quality weather``: error against run time of the weather (DESIGN §6).

The particle part (rain and snow: particle count and cube size against a dense reference) lives in
quality/precipitation.py; the fog part (against a multiple-scattering reference) joins here.

Usage: igserver quality weather [precipitation options, see igserver quality precipitation --help]
"""

from __future__ import annotations

from . import precipitation


def run(argv: list[str]) -> int:
    return precipitation.run(argv)
