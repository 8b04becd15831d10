"""Write small AVIRIS-NG, NEON and EMIT products with a known BRDF, to try the worked examples of docs/sensors.md.

Each product holds the demo's town (roof tile, concrete, grass, trees, bare soil and a pond;
``brdfcorr.chain.demo``: rendered with brdfcorr's model functions, Torrance-Sparrow for roofs and
concrete, the kernel-driven RTLSR model with illustrative weights for the rest) seen by a line
scanner flown north on 15 June 2026 with the sensor's field of view, written in the product's own
layout (``brdfcorr.testing``):

* ``aviris-ng/``: two orthorectified AVIRIS-NG-like lines over the same ground, at 08:00 and
  09:30 UTC, in ENVI format: reflectance ``ang20260615t080000_rfl`` (float32, BIL, wavelengths in
  the header) and its observation file ``ang20260615t080000_obs_ort`` (11 bands, JPL names), and
  the same for ``ang20260615t093000``; field of view 36 deg;
* ``neon/``: two NEON AOP directional reflectance flight lines (HDF5, reflectance x 10000 as
  int16, view angles and the flight line's sun in the metadata), the same ground flown at 09:00
  and 10:30 UTC; field of view 34 deg; site code DEMO (no NEON site);
* ``emit/``: an EMIT L2A reflectance granule and its L1B OBS granule at 08:00 UTC (NetCDF, swath layout with a
  geometry lookup table for a lon/lat grid, the swath turned 30 deg from north); field of view
  11 deg (EMIT's: an 80 km swath seen from 410 km).

The scenes are small (``--rows`` lines of 120 pixels of 5 m, the flying height set by the field of
view; six bands 450-860 nm, where a real product has hundreds of bands and thousands of lines) so
that the examples run in seconds:

    python examples/make_sensor_products.py products

The NEON and EMIT products are HDF5/NetCDF-4 files: writing them needs h5py and h5netcdf (the hdf5
extra, ``pip install 'brdfcorr[hdf5]'``; the environments of ``make demo`` and ``make test`` have
them); ``--sensor aviris-ng`` writes the ENVI lines alone.
"""

from __future__ import annotations

import argparse
import math
import sys
from importlib.util import find_spec
from pathlib import Path

from brdfcorr.chain.demo import demo_scene
from brdfcorr.testing import write_emit_granules, write_envi_line, write_neon_reflectance

#: Ground pixel [m] of every scene (the town's streets and houses are drawn in metres).
PIXEL = 5.0
#: Columns of every scene [-]: the flying height follows from the field of view.
COLUMNS = 120
#: Field of view [deg] of each sensor.
FOV = {"aviris-ng": 36.0, "neon": 34.0, "emit": 11.0}
#: Start times (UTC) of each sensor's lines: the airborne sensors fly the same ground twice, so that
#: the pooled fit sees two sun positions (one line's narrow view-angle range alone does not separate
#: the kernel-driven model's three terms).
LINES = {"aviris-ng": ("08:00", "09:30"), "neon": ("09:00", "10:30"), "emit": ("08:00",)}


def scene(sensor: str, rows: int, time: str):
    """The demo town seen by ``sensor`` at ``time`` (HH:MM UTC, 15 June 2026): ``COLUMNS`` columns of
    ``PIXEL`` m."""
    altitude = COLUMNS * PIXEL / (2.0 * math.tan(math.radians(FOV[sensor] / 2.0)))
    return demo_scene(rows=rows, pixel=PIXEL, altitude=altitude, fov=FOV[sensor], time=f"2026-06-15T{time}:00+00:00")


def missing_hdf5(sensors: list[str]) -> str | None:
    """What to install when ``sensors`` include HDF5/NetCDF-4 products (NEON, EMIT) and h5py or
    h5netcdf is not installed; None when nothing is missing."""
    hdf5 = [sensor.upper() for sensor in sensors if sensor in ("neon", "emit")]
    missing = [name for name in ("h5py", "h5netcdf") if find_spec(name) is None]
    if not hdf5 or not missing:
        return None
    return (f"the {' and '.join(hdf5)} products need {' and '.join(missing)} (not installed here): "
            "pip install 'brdfcorr[hdf5]' (in a clone made with `make demo`: .venv/bin/pip install h5py "
            "h5netcdf), or write the AVIRIS-NG lines alone with --sensor aviris-ng")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path, help="directory to write the products into")
    parser.add_argument("--rows", type=int, default=100, help="lines of each scene [default: 100]")
    parser.add_argument("--sensor", action="append", choices=sorted(FOV),
                        help="write only this sensor's products (repeatable) [default: all]")
    args = parser.parse_args(argv)
    sensors = args.sensor or sorted(FOV)
    missing = missing_hdf5(sensors)
    if missing:  # before anything is written
        sys.exit(f"make_sensor_products.py: error: {missing}")
    written: list[Path] = []
    if "aviris-ng" in sensors:
        for time in LINES["aviris-ng"]:
            line = scene("aviris-ng", args.rows, time)
            written += write_envi_line(args.output / "aviris-ng", line, f"ang20260615t{time[:2]}{time[3:5]}00",
                                       altitude=line.attrs["altitude_m"]).values()
    if "neon" in sensors:
        for time in LINES["neon"]:
            line = scene("neon", args.rows, time)
            written.append(write_neon_reflectance(args.output / "neon", line, flight_line=f"{time[:2]}{time[3:5]}00"))
    if "emit" in sensors:
        line = scene("emit", args.rows, LINES["emit"][0])
        written += write_emit_granules(args.output / "emit", line, heading=30.0,
                                       altitude=line.attrs["altitude_m"]).values()
    for path in written:
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
