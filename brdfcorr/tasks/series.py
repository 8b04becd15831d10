"""A time series of product folders as one lazy cube for notebooks: :func:`open_products`.

Sentinel-2 L2A SAFE folders or Landsat Collection-2 L2 folders of one tile (or path/row), opened
as a (time, band, y, x) reflectance cube with their (time, y, x) sun and view angles and the
c-factor table of their bands, so that one call of the ``.brdf`` accessor gives the NBAR of every
date as ``brdfcorr nbar`` gives it for each folder alone (docs/time-series.md)::

    series = open_products(sorted(Path("tiles").glob("*.SAFE")))
    nbar, qa = series.reflectance.brdf.normalize(None, series.angles, series.table, reference={"sza": 45.0})

Nothing is read until the result is computed or plotted, except each folder's metadata.

The command line takes the same folders as files (:func:`product_sources`): ``brdfcorr fit-classes``
over the dates (their bands stacked as virtual rasters in a scratch folder, their angles from each
product) and ``brdfcorr correct`` of one date with the fitted table. Each product is identified
once per run (:func:`find_products`, its metadata read) and then handed on as found: to the output
guard (:func:`product_files`) and to the stacking (:func:`stacked_products`).
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import xarray as xr

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.folders import ProductFolder, open_stack, write_stack
from brdfcorr.io.sensors.inputs import is_product
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.nbar import NBAR_CHUNK, find_product_or_item, nbar_table, refuse_archive

__all__ = ["ProductSeries", "open_products", "is_product", "find_products", "product_sources", "product_files",
           "stacked_products"]

#: A date in a product folder's name (Sentinel-2 ``20190425T132241``, Landsat ``20110306``).
_NAME_DATE = re.compile(r"_(\d{8}(?:T\d{6})?)_")


@dataclass(frozen=True)
class ProductSeries:
    """Product folders of one grid as a time series (:func:`open_products`).

    Attributes
    ----------
    reflectance : DataArray
        Reflectance factors [1] (time, band, y, x), lazily; masked pixels (clouds, shadows, fill)
        NaN; ``band`` the band names, ``wavelength`` their centres [nm]; ``time`` the sensing times.
    angles : Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] (time, y, x) on the same grid, from each folder's
        own angle source (Sentinel-2 ``MTD_TL.xml``, the mean of the bands' view grids; Landsat
        angle bands or ``ANG.txt``).
    table : ParameterTable
        One class (id 1) with the coefficient set's weights of the bands at their centres [nm]
        (:func:`brdfcorr.tasks.nbar.nbar_table`): matched to a cube's bands by its ``wavelength``
        coordinate, in any order or subset.
    products : tuple of ProductFolder
        The folders in time order.
    """

    reflectance: xr.DataArray
    angles: xr.Dataset
    table: ParameterTable
    products: tuple[ProductFolder, ...]


def open_products(folders: Iterable[str | os.PathLike], *, resolution: int | None = None,
                  bands: Sequence[str] | None = None, masked: Sequence[int] | None = None,
                  coefficients: str = "roy2017", chunks: int = NBAR_CHUNK) -> ProductSeries:
    """Product folders of one tile as a lazy (time, band, y, x) cube with its angles and c-factor table.

    Parameters
    ----------
    folders : iterable of path-like
        Sentinel-2 L2A ``.SAFE`` folders, Sentinel-2 STAC item files with local assets
        (:mod:`brdfcorr.io.sensors.stac`) or Landsat Collection-2 L2 folders, all of one sensor, on
        one grid (one tile or path/row, one resolution); in any order (sorted by sensing time).
    resolution, bands, masked :
        As for ``brdfcorr nbar`` (:func:`brdfcorr.tasks.nbar.nbar_files`): Sentinel-2 pixel size
        [m] (default 20), band names in output order, SCL classes or QA_PIXEL bits made NaN.
    coefficients : {"roy2017", "roy2016"}
        The built-in coefficient set of :attr:`ProductSeries.table`.
    chunks : int
        Spatial chunk size [pixels] of the cube and its angles.

    Returns
    -------
    ProductSeries

    Raises
    ------
    SensorInputError
        No folder; a folder that is no product (as ``brdfcorr nbar`` says it); folders of other
        sensors, bands or grids than the first (named with what differs).
    """
    products = find_products(folders, resolution=resolution, bands=bands, masked=masked)
    if not products:
        raise SensorInputError("open_products: no product folder given")
    dates = []
    for product in products:
        stack = open_stack(product, chunks)
        angles = read_angles(product.angles_kind, product.angles, like=stack, chunks=chunks,
                             **product.angle_options)
        dates.append((_sensing_time(product, angles), product, stack, angles))
    dates.sort(key=lambda date: date[0])
    first = dates[0][2]
    for _, product, stack, _ in dates[1:]:
        _check_alike(first, stack, product)
    times = pd.DatetimeIndex([date[0] for date in dates], name="time")
    reflectance = xr.concat([date[2] for date in dates], dim=times, combine_attrs="drop_conflicts")
    angles = xr.concat([date[3] for date in dates], dim=times, combine_attrs="drop_conflicts")
    return ProductSeries(reflectance, angles, nbar_table(products[0], coefficients),
                         tuple(date[1] for date in dates))


def _sensing_time(product: ProductFolder, angles: xr.Dataset) -> pd.Timestamp:
    """The sensing time of a product: its angle source's (Sentinel-2 ``SENSING_TIME``), else the
    date in its folder's name (Landsat's acquisition date)."""
    text = angles.attrs.get("sensing_time")
    if text is None:
        found = _NAME_DATE.search(product.path.name)
        if found is None:
            raise SensorInputError(f"{product.path}: no sensing time (no date in the folder's name)")
        text = found.group(1)
    time = pd.Timestamp(text)
    return time.tz_localize(None) if time.tzinfo else time


def _check_alike(first: xr.DataArray, stack: xr.DataArray, product: ProductFolder) -> None:
    """Refuse a folder whose sensor, bands or grid differ from the first folder's."""
    same_grid = (stack.rio.crs == first.rio.crs and stack.rio.transform() == first.rio.transform()
                 and stack.shape == first.shape)
    differs = [what for what, same in (
        ("sensor", stack.attrs["sensor"] == first.attrs["sensor"]),
        ("bands", list(stack["band"].values) == list(first["band"].values)),
        ("grid (CRS, transform, size)", same_grid),
    ) if not same]
    if differs:
        raise SensorInputError(f"{product.path}: its {', '.join(differs)} differ from those of "
                               f"{first.attrs['product']}; a series is one sensor's bands on one grid")


def product_files(products: Iterable[ProductFolder]) -> list[tuple[str, Path]]:
    """Every file the products read (:attr:`ProductFolder.files`), named by role and product
    (``band B04 of NAME.SAFE``): inputs of the output guard (:func:`brdfcorr.io.paths.check_outputs`)
    of ``correct`` and ``fit-classes``, which never overwrite them."""
    return [(f"{role} of {product.path.name}", path) for product in products for role, path in product.files]


def find_products(paths: Iterable[str | os.PathLike], *, resolution: int | None = None,
                  bands: Sequence[str] | None = None, masked: Sequence[int] | None = None) -> list[ProductFolder]:
    """The product of each path, identified once for the run (its metadata read): the run then
    hands it on (:func:`product_files`, :func:`stacked_products`) instead of finding it again.

    Parameters
    ----------
    paths : iterable of path-like
        Sentinel-2 L2A SAFE folders, Landsat Collection-2 L2 folders or Sentinel-2 STAC item files
        (:func:`brdfcorr.tasks.nbar.find_product_or_item`); each product's ``path`` is the path as
        given, which errors, labels and reports name.
    resolution, bands, masked :
        As for :func:`open_products`.

    Raises
    ------
    SensorInputError
        A path in an archive, or no product (as ``brdfcorr nbar`` says it), named.
    """
    products = []
    for path in paths:
        refuse_archive(path)
        products.append(find_product_or_item(path, resolution=resolution, bands=bands, masked=masked))
    return products


@contextlib.contextmanager
def stacked_products(products: Sequence[ProductFolder], *, chunks: int = NBAR_CHUNK) -> Iterator[list[dict]]:
    """Each product's scene files (:func:`product_sources`), stacked in one scratch folder that is
    removed at the end of the ``with`` block (the run that reads them)."""
    with tempfile.TemporaryDirectory(prefix="brdfcorr-products-") as folder:
        yield [product_sources(product, folder, chunks=chunks) for product in products]


def product_sources(product: ProductFolder, scratch: str | os.PathLike, *, chunks: int = NBAR_CHUNK) -> dict:
    """A product (:func:`find_products`) as the files of one scene, for ``fit-classes`` and ``correct``.

    The product's bands are stacked, masked and scaled as ``brdfcorr nbar`` stacks them: a GDAL
    virtual raster (and its mask) written into the folder ``scratch``
    (:func:`brdfcorr.io.sensors.folders.write_stack`, nothing copied); the angles are the
    product's own source. The scene then reads the values that :func:`open_products` gives for
    that date (a test compares a fit and a correction with the accessor's, value for value).
    The product's metadata is not read again: it is the product found for the run.

    Parameters
    ----------
    product : ProductFolder
        A Sentinel-2 L2A SAFE folder, a Landsat Collection-2 L2 folder or a Sentinel-2 STAC item,
        as found (:func:`find_products`, :func:`brdfcorr.tasks.nbar.find_product_or_item`).
    scratch : path-like
        An existing folder for the stack; the caller removes it after the fit or correction.
    chunks : int
        Block size [pixels] of the stack's mask file, as for :func:`open_products`.

    Returns
    -------
    dict
        Keywords of :class:`brdfcorr.io.scene.SceneSources` (without ``classes``): ``image`` (the
        stack), ``label`` (the product's path as given: errors and reports name the product, not
        the scratch stack), ``angles``, ``angles_kind``, ``angle_options`` and, where every band
        has the same, the product's ``scale`` and ``offset`` (reflectance = DN x scale + offset).
    """
    folder = Path(scratch) / f"{len(list(Path(scratch).iterdir()))}"  # one per product: the names may repeat
    folder.mkdir()
    stack = write_stack(product, folder / f"{product.path.name}.vrt", chunks=chunks)
    scales, offsets = set(product.scales), set(product.offsets)
    known = {"scale": scales.pop(), "offset": offsets.pop()} if len(scales) == len(offsets) == 1 else {}
    return {"image": stack, "label": str(product.path), "angles": product.angles, "angles_kind": product.angles_kind,
            "angle_options": dict(product.angle_options), **known}
