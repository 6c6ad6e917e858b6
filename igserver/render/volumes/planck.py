"""A blackbody's colour and luminous efficacy from Planck's law and the CIE 1931 observer.

Spectral radiance B(lambda, T) = 2 h c^2 lambda^-5 / (exp(h c / (lambda k T)) - 1), integrated over
360-830 nm at 1 nm against the CIE 1931 2-degree colour-matching functions in the multi-lobe
Gaussian fit of Wyman, Sloan & Shirley ("Simple analytic approximations to the CIE XYZ color
matching functions", JCGT 2, 2013; y-bar is the photopic V(lambda)): XYZ, then linear Rec. 709 / sRGB
by the D65 matrix whose Y row is photometry.LUMA. Below ~2500 K a blackbody lies outside the Rec. 709
gamut (its blue is slightly negative); the channels are clipped at 0, which moves the chromaticity by
0.007 in u'v' at 1500 K, 0.004 at 1700 K and not at all from ~1900 K.

Luminous efficacy of the radiation (lm/W) = 683 int V B / int B, with int B = sigma T^4 / pi: 0.085
at 1500 K, 0.35 at 1700 K, 1.9 at 2042 K (where the luminance is 60 cd/cm^2, the platinum point of
the old candela).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...photometry import LUMA

H = 6.62607015e-34  # J s
C = 2.99792458e8  # m/s
K_B = 1.380649e-23  # J/K
SIGMA = 5.670374419e-8  # W/m^2 K^4
KM = 683.0  # lm/W at 555 nm
WAVELENGTHS_NM = np.arange(360.0, 831.0, 1.0)
# linear Rec. 709 (D65) -> XYZ (IEC 61966-2-1); its Y row is LUMA
RGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805], LUMA, [0.0193, 0.1192, 0.9505]])
RGB_TO_XYZ.setflags(write=False)


def _lobe(lam, mu, s_below, s_above):
    s = np.where(lam < mu, s_below, s_above)
    return np.exp(-0.5 * ((lam - mu) / s) ** 2)


def cie_1931(lam_nm) -> np.ndarray:
    """(..., 3) x-bar, y-bar, z-bar at ``lam_nm`` (Wyman, Sloan & Shirley 2013, multi-lobe fit)."""
    lam = np.asarray(lam_nm, dtype=np.float64)
    x = 1.056 * _lobe(lam, 599.8, 37.9, 31.0) + 0.362 * _lobe(lam, 442.0, 16.0, 26.7) - 0.065 * _lobe(lam, 501.1, 20.4, 26.2)
    y = 0.821 * _lobe(lam, 568.8, 46.9, 40.5) + 0.286 * _lobe(lam, 530.9, 16.3, 31.1)
    z = 1.217 * _lobe(lam, 437.0, 11.8, 36.0) + 0.681 * _lobe(lam, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=-1)


_CMF = cie_1931(WAVELENGTHS_NM)


def spectral_radiance(kelvin: float) -> np.ndarray:
    """W / (m^2 sr m) at WAVELENGTHS_NM."""
    lam = WAVELENGTHS_NM * 1e-9
    return 2.0 * H * C**2 / lam**5 / np.expm1(H * C / (lam * K_B * max(kelvin, 100.0)))


def blackbody_xyz(kelvin: float) -> np.ndarray:
    """CIE XYZ of a blackbody's radiance, Y in cd/m^2."""
    return KM * (spectral_radiance(kelvin)[:, None] * _CMF).sum(axis=0) * 1e-9  # 1 nm steps


def luminous_efficacy(kelvin: float) -> float:
    """lm/W of a blackbody's radiation at ``kelvin``."""
    return float(blackbody_xyz(kelvin)[1] / (SIGMA * kelvin**4 / np.pi))


_T_TABLE = np.arange(800.0, 4001.0, 5.0)
_EFFICACY_TABLE = np.array([luminous_efficacy(t) for t in _T_TABLE])


def efficacy_temperature(efficacy: float) -> float:
    """K, the blackbody temperature whose luminous efficacy is ``efficacy`` lm/W (monotonic in T;
    interpolated in log efficacy, clamped to 800-4000 K)."""
    log_eff = np.log(np.clip(efficacy, _EFFICACY_TABLE[0], _EFFICACY_TABLE[-1]))
    return float(np.interp(log_eff, np.log(_EFFICACY_TABLE), _T_TABLE))


@lru_cache(maxsize=512)
def _light_rgb(kelvin: int) -> tuple[float, float, float]:
    rgb = np.maximum(np.linalg.solve(RGB_TO_XYZ, blackbody_xyz(float(kelvin))), 0.0)
    rgb = rgb / float(rgb @ LUMA)
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


_RGB_TABLE_T = np.arange(500.0, 6001.0, 5.0)
_RGB_TABLE = np.maximum(np.linalg.solve(RGB_TO_XYZ, np.stack([blackbody_xyz(t) for t in _RGB_TABLE_T]).T).T, 0.0)
_RGB_TABLE /= _RGB_TABLE.max(axis=1, keepdims=True)


def blackbody_chromaticity(kelvin) -> np.ndarray:
    """(..., 3) linear Rec. 709 colour of a blackbody at ``kelvin`` (array or scalar), its brightest
    channel 1: the integrated Planck x CIE colour, tabulated every 5 K over 500-6000 K and
    interpolated per channel (within 0.002 of the direct integral; clamped outside the range)."""
    t = np.clip(np.asarray(kelvin, dtype=np.float64), _RGB_TABLE_T[0], _RGB_TABLE_T[-1])
    return np.stack([np.interp(t, _RGB_TABLE_T, _RGB_TABLE[:, c]) for c in range(3)], axis=-1)


def blackbody_light_rgb(kelvin: float) -> np.ndarray:
    """Linear Rec. 709 colour of a blackbody at ``kelvin`` (to the nearest kelvin), unit luminance."""
    return np.array(_light_rgb(int(round(kelvin))))
