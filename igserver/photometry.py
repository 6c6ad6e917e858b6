"""Photometric constants shared by the renderer, the quality studies and the tests (numpy only, so
every layer can import it)."""

from __future__ import annotations

import numpy as np

# Relative luminance of linear Rec. 709 / sRGB primaries with a D65 white (ITU-R BT.709, the Y row of
# the RGB -> XYZ matrix): Y = LUMA . rgb, in rgb's units (cd/m^2 for radiance, lux for illuminance).
# The weights sum to 1, so a grey of value v has luminance v. Read-only: one array shared by all.
LUMA = np.array([0.2126, 0.7152, 0.0722])
LUMA.setflags(write=False)
