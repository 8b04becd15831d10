"""Convert the MYD13A1 layers of cogeotiff/rio-tiler-pds's test fixtures into the GeoTIFFs brdfcorr reads.

Source (README.md here): 12 single-band GeoTIFFs of the MODIS/Aqua 16-day vegetation index
composite MYD13A1 collection 6, tile h30v10, 1-16 June 2020, the 2400 x 2400 tile thinned by 5
to 480 x 480 pixels of 2316.56 m. Run with brdfcorr's environment::

    python make_subset.py SOURCE_DIRECTORY OUTPUT_DIRECTORY

It writes

- ``reflectance.tif``: float32 surface reflectance factors [1] of the four reflectance layers,
  sorted by band centre (blue 469, red 645, NIR 858.5, MIR 2130 nm), the product's 1e-4 applied;
  NaN where the layer holds its fill value (-1000) and where the pixel reliability (layer 12) is
  not 0 ("good data": clouds, snow, marginal data and fill are left out);
- ``angles.tif``: float32, bands sza, vza, raa [deg] (brdfcorr's 3-band angle raster of products
  that give the relative azimuth only, ``docs/conventions.md``), the product's 0.01 deg applied;
  raa is the product's relative azimuth, as in MOD09 (view azimuth - sun azimuth);
- ``day.tif``: int16, the composite day of year of each pixel (layer 11; -1 where none): the day,
  and so the orbit, each pixel was taken from.

All on the product's sinusoidal grid, as the source files give it.
"""

import sys
from pathlib import Path

import numpy as np
import rasterio

STEM = "MYD13A1.A2020153.h30v10.006.2020170024036"
#: Layer suffix -> centre [nm] of the reflectance layers (MOD13 user's guide, collection 6).
CENTRES = {"BR_B06": 469.0, "RR_B04": 645.0, "NIRR_B05": 858.5, "MIRR_B07": 2130.0}


def read(source: Path, suffix: str) -> tuple[np.ndarray, dict]:
    with rasterio.open(source / f"{STEM}_{suffix}.TIF") as dataset:
        return dataset.read(1), dataset.profile


def write(path: Path, bands: list[np.ndarray], descriptions: list[str], profile: dict, dtype: str, nodata,
          tags: dict) -> None:
    profile = {**profile, "count": len(bands), "dtype": dtype, "nodata": nodata, "compress": "deflate",
               "predictor": 3 if dtype == "float32" else 2, "tiled": False}
    with rasterio.open(path, "w", **profile) as sink:
        for index, (band, description) in enumerate(zip(bands, descriptions), start=1):
            sink.write(band.astype(dtype), index)
            sink.set_band_description(index, description)
        sink.update_tags(**tags)


def main(source: str, output: str) -> None:
    source_dir, out = Path(source), Path(output)
    out.mkdir(parents=True, exist_ok=True)
    reliability, profile = read(source_dir, "PR_B12")
    good = reliability == 0
    cube = []
    for suffix in CENTRES:
        raw, _ = read(source_dir, suffix)
        cube.append(np.where(good & (raw != -1000), raw * 1e-4, np.nan))
    centres = list(CENTRES.values())
    write(out / "reflectance.tif", cube, [f"{c:g} nm" for c in centres], profile, "float32", np.nan,
          {"wavelength": ",".join(f"{c:g}" for c in centres), "wavelength_units": "nm", "source": STEM})
    angles = []
    for suffix, fill in (("SZA_B09", -10000), ("VZA_B08", -10000), ("RAA_B10", -4000)):
        raw, _ = read(source_dir, suffix)
        angles.append(np.where(raw != fill, raw * 0.01, np.nan))
    write(out / "angles.tif", angles, ["sza", "vza", "raa"], profile, "float32", np.nan,
          {"source": STEM, "raa": "view azimuth - sun azimuth [deg], the product's relative azimuth"})
    day, _ = read(source_dir, "CDOY_B11")
    write(out / "day.tif", [day], ["composite day of year"], profile, "int16", -1, {"source": STEM})


if __name__ == "__main__":
    main(*sys.argv[1:3])
