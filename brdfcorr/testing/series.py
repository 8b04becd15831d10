"""A Sentinel-2 time series whose ground has a BRDF: :func:`write_sentinel2_series`.

:func:`brdfcorr.testing.write_sentinel2_safe` writes the same DNs for every date of one seed, so a
series of it has no angular signal to fit. Here each date's 20 m bands are the same ground seen
under that date's sun, through a known Ross-Thick Li-Sparse-R shape:

    rho(date, band, y, x) = rho_ground(band, y, x) * f(sza, vza, raa) / f(45, 0, 0)

with f = 1 + k_vol K_vol + k_geo K_geo (Lucht et al. 2000, eq. 37, weights relative to f_iso), the
angles those ``brdfcorr nbar`` reads from the date's ``MTD_TL.xml`` on the 20 m grid, and the DNs
rounded as the product stores them (reflectance = (DN - 1000) / 10000). The 10 m files are left as
written (random, no BRDF). A class map (two classes: the tile's west and east halves, 0 on the
cloudy first row) is written beside the folders as ``classes.tif``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["write_sentinel2_series", "SERIES_SHAPE"]

#: The series' shape: RTLSR k_vol = f_vol / f_iso and k_geo = f_geo / f_iso of every band.
SERIES_SHAPE = (0.5, 0.15)


def write_sentinel2_series(directory: str | os.PathLike, *, dates: int = 4, size: int = 32, seed: int = 0,
                           shape: tuple[float, float] = SERIES_SHAPE) -> list[Path]:
    """``dates`` SAFE folders of one tile, ten days apart from 1 April 2024, the sun zenith falling
    from 55 to 30 deg, the 20 m bands carrying the RTLSR ``shape`` (module docstring); and
    ``classes.tif`` in ``directory``. Returns the folders in date order."""
    import rasterio

    from brdfcorr.testing.products import write_sentinel2_safe

    directory = Path(directory)
    times = pd.date_range("2024-04-01 10:30", periods=dates, freq="10D")
    folders = []
    for when, sun in zip(times, np.linspace(55.0, 30.0, dates)):
        safe = write_sentinel2_safe(directory, size=size, seed=seed, sensed=(when.strftime("%Y%m%dT%H%M%S"),
                                                                            (sun, sun + 2.0)))
        factor = _factor(safe, shape)
        for path in sorted(safe.glob("GRANULE/*/IMG_DATA/R20m/*_20m.jp2")):
            if "_SCL_" in path.name:
                continue
            with rasterio.open(path, "r+") as dataset:
                counts = dataset.read(1).astype(float)
                seen = (counts - 1000.0) / 10000.0 * factor
                dataset.write(np.clip(np.rint(seen * 10000.0 + 1000.0), 1, 65535).astype("uint16"), 1)
        folders.append(safe)
    _write_classes(folders[0], directory / "classes.tif")
    return folders


def _factor(safe: Path, shape: tuple[float, float]) -> np.ndarray:
    """f(sza, vza, raa) / f(45, 0, 0) (y, x) of the RTLSR ``shape`` on the folder's 20 m grid."""
    from brdfcorr.geometry import relative_azimuth
    from brdfcorr.io.sensors import read_angles
    from brdfcorr.io.sensors.folders import find_product, open_stack
    from brdfcorr.models import get_model

    product = find_product(safe)
    angles = read_angles(product.angles_kind, product.angles, like=open_stack(product), **product.angle_options)
    sza, vza = (np.asarray(angles[name].values, dtype=float) for name in ("sza", "vza"))
    raa = relative_azimuth(np.asarray(angles["saa"].values), np.asarray(angles["vaa"].values))
    model = get_model("ross_thick_li_sparse")
    weights = {"f_iso": 1.0, "f_vol": shape[0], "f_geo": shape[1]}
    return np.asarray(model(sza, vza, raa, **weights) / model(45.0, 0.0, 0.0, **weights), dtype=float)


def _write_classes(safe: Path, target: Path) -> None:
    """Two classes on the 20 m grid of ``safe``: 1 west, 2 east of the tile's middle, 0 on row 0."""
    import rasterio

    grid = next(safe.glob("GRANULE/*/IMG_DATA/R20m/*_B8A_20m.jp2"))
    with rasterio.open(grid) as source:
        profile = {"driver": "GTiff", "width": source.width, "height": source.height, "count": 1, "dtype": "uint8",
                   "crs": source.crs, "transform": source.transform, "nodata": 0}
    classes = np.where(np.arange(profile["width"]) < profile["width"] // 2, 1, 2).astype("uint8")
    classes = np.repeat(classes[None, :], profile["height"], axis=0)
    classes[0] = 0
    with rasterio.open(target, "w", **profile) as dataset:
        dataset.write(classes, 1)
