"""Write two small synthetic product folders for the NBAR examples of docs/sensors.md.

    python examples/nbar_products.py DIRECTORY [--size PIXELS]

DIRECTORY/S2A_MSIL2A_..._T23LLF_....SAFE: a Sentinel-2 L2A SAFE folder with synthetic granule
metadata (MTD_TL.xml: sun and view angle grids at 5 km), baseline 04.00 scaling and an SCL
(:func:`brdfcorr.testing.write_sentinel2_safe`); DIRECTORY/LE07_L2SP_..._02_T1: a Landsat 7
Collection-2 Level-2 folder with the four angle bands (SZA, SAA, VZA, VAA) and a QA_PIXEL band
(:func:`brdfcorr.testing.write_landsat_c2`). Their reflectances are random (0.05-0.4): the
examples show the commands and the files, not a landscape. Real folders are used the same way.
"""

import argparse
from pathlib import Path

from brdfcorr.testing import write_landsat_c2, write_sentinel2_safe


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="where to write the two folders (created)")
    parser.add_argument("--size", type=int, default=64, help="pixels per side (20 m Sentinel-2, 30 m Landsat)")
    args = parser.parse_args()
    safe = write_sentinel2_safe(args.directory, size=args.size)
    landsat = write_landsat_c2(args.directory, size=args.size, angle_bands=True)
    print(f"wrote {safe}\nwrote {landsat}")


if __name__ == "__main__":
    main()
