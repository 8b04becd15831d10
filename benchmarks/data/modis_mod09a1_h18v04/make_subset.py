"""Convert the MOD09A1 test granule of ropensci/MODIStsp into the GeoTIFFs brdfcorr reads.

Source: ``inst/testdata/MOD09A1.A2017193.h18v04.006.2017202035302.hdf.zip`` of
https://github.com/ropensci/MODIStsp (commit d8193da936eb255ad7c977760f5e9881682a4de3), a
73 x 66 pixel cut of the MODIS/Terra 8-day surface reflectance composite MOD09A1 collection 6,
tile h18v04, 12-19 July 2017 (NASA LP DAAC, doi:10.5067/MODIS/MOD09A1.006; README.md here).

Run where the unzipped HDF4 file and a Python with ``pyhdf``, ``numpy`` and ``rasterio`` exist
(brdfcorr's own environment has no HDF4 driver)::

    python make_subset.py MOD09A1.A2017193.h18v04.006.2017202035302.hdf OUTPUT_DIRECTORY

It writes

- ``reflectance.tif``: float32 surface reflectance factors [1] of the seven land bands, sorted by
  band centre (469, 555, 645, 858.5, 1240, 1640, 2130 nm; the product stores them as bands
  1-7 = 645, 858.5, 469, 555, 1240, 1640, 2130 nm), the product's scale 0.0001 applied; NaN where
  the product's fill value is, and where its 500 m state flags say cloud (bits 0-1 not 00),
  cloud shadow (bit 2), not land (bits 3-5 not 001) or internal cloud (bit 10) (MOD09 user's
  guide, collection 6, table 13);
- ``angles.tif``: float32, bands sza, vza, raa [deg]: brdfcorr's 3-band angle raster of products
  that give the relative azimuth only (``docs/conventions.md``). raa is the product's relative
  azimuth, view azimuth - sun azimuth (0 at the hotspot, the sensor on the sun's side), in
  [-180, 180], as brdfcorr defines it; brdfcorr folds |raa| into [0, 180].

Both on the product's sinusoidal grid (sphere of radius 6371007.181 m, 463.3127 m pixels, the
upper-left corner from the file's StructMetadata).
"""

import re
import sys
from pathlib import Path

import numpy as np
import rasterio
from pyhdf.SD import SD, SDC
from rasterio.transform import from_origin

#: Product band -> centre [nm] (MOD09 user's guide, collection 6, table 1).
CENTRES = {"sur_refl_b01": 645.0, "sur_refl_b02": 858.5, "sur_refl_b03": 469.0, "sur_refl_b04": 555.0,
           "sur_refl_b05": 1240.0, "sur_refl_b06": 1640.0, "sur_refl_b07": 2130.0}
SINUSOIDAL = "+proj=sinu +lon_0=0 +x_0=0 +y_0=0 +R=6371007.181 +units=m +no_defs"


def scaled(hdf: SD, name: str) -> np.ndarray:
    """The dataset as float64 with its scale_factor applied, its _FillValue as NaN."""
    dataset = hdf.select(name)
    attributes = dataset.attributes()
    raw = dataset[:]
    values = raw.astype(np.float64) * float(attributes.get("scale_factor", 1.0))
    if "_FillValue" in attributes:
        values[raw == attributes["_FillValue"]] = np.nan
    return values


def clear_land(state: np.ndarray) -> np.ndarray:
    """True where the 500 m state flags say clear land: no cloud, shadow or internal cloud."""
    state = state.astype(np.int64)
    return (((state & 0b11) == 0) & ((state >> 2) & 1 == 0) & (((state >> 3) & 0b111) == 1)
            & ((state >> 10) & 1 == 0))


def grid(hdf: SD, shape: tuple[int, int]):
    """The affine transform from the upper-left and lower-right corners in StructMetadata.0."""
    text = hdf.attributes()["StructMetadata.0"]
    left, top = map(float, re.search(r"UpperLeftPointMtrs=\(([^,]+),([^)]+)\)", text).groups())
    right, bottom = map(float, re.search(r"LowerRightMtrs=\(([^,]+),([^)]+)\)", text).groups())
    return from_origin(left, top, (right - left) / shape[1], (top - bottom) / shape[0])


def write(path: Path, bands: list[np.ndarray], descriptions: list[str], transform, tags: dict) -> None:
    profile = {"driver": "GTiff", "dtype": "float32", "count": len(bands), "height": bands[0].shape[0],
               "width": bands[0].shape[1], "crs": SINUSOIDAL, "transform": transform, "nodata": np.nan,
               "compress": "deflate", "predictor": 3}
    with rasterio.open(path, "w", **profile) as dst:
        for index, (band, description) in enumerate(zip(bands, descriptions), start=1):
            dst.write(band.astype(np.float32), index)
            dst.set_band_description(index, description)
        dst.update_tags(**tags)


def main(source: str, output: str) -> None:
    hdf = SD(source, SDC.READ)
    keep = clear_land(hdf.select("sur_refl_state_500m")[:])
    order = sorted(CENTRES, key=CENTRES.get)
    cube = [np.where(keep, scaled(hdf, name), np.nan) for name in order]
    transform = grid(hdf, cube[0].shape)
    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    centres = [CENTRES[name] for name in order]
    write(out / "reflectance.tif", cube, [f"{c:g} nm" for c in centres], transform,
          {"wavelength": ",".join(f"{c:g}" for c in centres), "wavelength_units": "nm",
           "source": Path(source).name, "bands": ",".join(order)})
    sza, vza, raz = (scaled(hdf, name) for name in ("sur_refl_szen", "sur_refl_vzen", "sur_refl_raz"))
    write(out / "angles.tif", [sza, vza, raz], ["sza", "vza", "raa"], transform,
          {"source": Path(source).name, "raa": "view azimuth - sun azimuth [deg], the product's sur_refl_raz"})


if __name__ == "__main__":
    main(*sys.argv[1:3])
