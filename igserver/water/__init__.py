"""The sea's wave maths, in float64 numpy: the ONE source both the GPU pass and the host queries use.

- ``dispersion``: k from ω and depth (ω² = g k tanh(k h)), group velocity.
- ``spectrum``: wind / WMO sea state → a deterministic set of Gerstner waves (JONSWAP + spreading).
- ``bathymetry``: depth from the scene (uniform, slope, height-map asset) and the per-wave phase /
  amplitude field over it (refraction, shoaling, breaking), integrated once per bathymetry + wave set.
- ``surface``: displacement, height, normal and velocity at points and a sim_time; its wave sums in
  ``wave_sums``, the field sampled at points in ``field_sampling``, scratch arrays in ``workspace``.
"""

from .surface import SeaSurface, sea_surface

__all__ = ["SeaSurface", "sea_surface"]
