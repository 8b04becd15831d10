"""Write a time series of small synthetic Sentinel-2 L2A SAFE folders for docs/time-series.md.

    python examples/sentinel2_series.py DIRECTORY [--dates 10] [--size PIXELS] [--brdf]

DIRECTORY/S2A_MSIL2A_<date>T103000_..._T23LLF_....SAFE: one folder per date, ten days apart from
1 April 2024, of one tile and one ground (the same DNs: :func:`brdfcorr.testing.write_sentinel2_safe`
with one seed), each with granule metadata (MTD_TL.xml) of its own date and sun: the sun zenith
falls from 55 to about 30 deg through the spring. The reflectances are random (0.05-0.4) and do
not change with the sun: the example shows the calls and the files, not a landscape. Real SAFE
folders are opened the same way. With ``--brdf`` the 20 m bands are that ground seen through a known
RTLSR shape under each date's sun, and a class map ``classes.tif`` is written beside the folders
(:func:`brdfcorr.testing.write_sentinel2_series`): a series to fit.
"""

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from brdfcorr.testing import write_sentinel2_safe, write_sentinel2_series


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="where to write the folders (created)")
    parser.add_argument("--dates", type=int, default=10, help="how many dates, ten days apart")
    parser.add_argument("--size", type=int, default=32, help="pixels per side (20 m)")
    parser.add_argument("--brdf", action="store_true", help="the 20 m bands with a BRDF, and classes.tif")
    args = parser.parse_args()
    if args.brdf:
        for safe in write_sentinel2_series(args.directory, dates=args.dates, size=args.size):
            print(f"wrote {safe}")
        print(f"wrote {args.directory / 'classes.tif'}")
        return
    dates = pd.date_range("2024-04-01 10:30", periods=args.dates, freq="10D")
    for date, sun in zip(dates, np.linspace(55.0, 30.0, args.dates)):
        safe = write_sentinel2_safe(args.directory, size=args.size, seed=0,
                                    sensed=(date.strftime("%Y%m%dT%H%M%S"), (sun, sun + 2.0)))
        print(f"wrote {safe}")


if __name__ == "__main__":
    main()
