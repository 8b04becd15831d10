"""Small synthetic scenes and rasters for tests, benchmarks, examples and the demo (never committed
binaries); sensor products in their real layouts are written by :mod:`brdfcorr.testing.products`.

A scene is rendered from known parameters with the public model functions
(:meth:`brdfcorr.models.Model.__call__`, one full evaluation per class and band), independently of
the block machinery of :mod:`brdfcorr.correction`::

    reflectance(band, y, x) = brightness(y, x) * f_class(y, x)(sza, vza, phi; p(band))

so that normalizing a scene rendered at geometry A to geometry B must give the scene rendered at
B (the brightness cancels in the ratio).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.writer import wavelength_text
from brdfcorr.params import ParameterTable
from brdfcorr.testing import products, series, small_scenes
from brdfcorr.testing.products import *  # noqa: F403 (the product writers, re-exported)
from brdfcorr.testing.series import *  # noqa: F403 (a product series with a BRDF, re-exported)
from brdfcorr.testing.small_scenes import *  # noqa: F403 (the fit's small scenes, re-exported)

__all__ = [
    "example_table", "file_digests", "synthetic_angles", "synthetic_classes", "render", "synthetic_scene",
    "write_scene", "write_scene_chain", "georeference", *products.__all__, *series.__all__,
    *small_scenes.__all__,
]

#: Grid used by the helpers: 10 m pixels of UTM zone 32N.
CRS = "EPSG:32632"
ORIGIN = (500000.0, 5400000.0)
PIXEL = 10.0


def example_table(reference: dict | None = None) -> ParameterTable:
    """A table with one class per surface model family (values from paper 003 Table 1, and made-up
    spectral values for the empirical class): ids 1 (roof tile, TS), 2 (grass, empirical, per
    wavelength 450-850 nm), 3 (paving, simplified TS), 4 (flat, Lambertian)."""
    return ParameterTable(
        reference=reference,
        classes=[
            {"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
             "params": {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}},
            {"id": 2, "name": "grass", "model": "empirical", "wavelengths": [450, 550, 650, 850],
             "params": {"a": [0.01, 0.02, 0.015, 0.05], "b": 1.0, "c": 0.02,
                        "t0": [0.02, 0.05, 0.03, 0.30]}},
            {"id": 3, "name": "paving", "model": "torrance_sparrow_simplified",
             "params": {"t0": 0.05, "t1": 0.3, "w": 0.06, "n": 1.6, "k": 0.1}},
            {"id": 4, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}},
        ],
    )


def georeference(array: xr.DataArray, crs: str = CRS) -> xr.DataArray:
    """Give a (…, y, x) array the helpers' grid: x/y pixel-centre coords, CRS and transform."""
    import rioxarray  # noqa: F401  (registers .rio)

    ny, nx = array.shape[-2:]
    x = ORIGIN[0] + PIXEL * (np.arange(nx) + 0.5)
    y = ORIGIN[1] - PIXEL * (np.arange(ny) + 0.5)
    array = array.assign_coords(x=("x", x), y=("y", y))
    return array.rio.write_crs(crs).rio.write_transform(array.rio.transform(recalc=True))


def synthetic_angles(ny: int, nx: int, sza=(30.0, 40.0), vza_max: float = 25.0, saa: float = 150.0,
                     dtype=np.float32) -> dict[str, np.ndarray]:
    """Smooth angle fields [deg] of a push-broom line: sza ramps along y, vza across x (sensor
    looking to either side, vaa = 90 or 270), constant saa."""
    rows = np.linspace(0.0, 1.0, ny)[:, None]
    cols = np.linspace(-1.0, 1.0, nx)[None, :]
    sza_field = np.broadcast_to(sza[0] + (sza[1] - sza[0]) * rows, (ny, nx))
    vza_field = np.broadcast_to(vza_max * np.abs(cols), (ny, nx))
    vaa_field = np.broadcast_to(np.where(cols < 0, 270.0, 90.0), (ny, nx))
    return {
        "sza": np.ascontiguousarray(sza_field, dtype=dtype),
        "saa": np.full((ny, nx), saa, dtype=dtype),
        "vza": np.ascontiguousarray(vza_field, dtype=dtype),
        "vaa": np.ascontiguousarray(vaa_field, dtype=dtype),
    }


def synthetic_classes(ny: int, nx: int, ids=(1, 2, 3, 4), seed: int = 0, dtype=np.uint8) -> np.ndarray:
    """A class map of random 4x4-pixel patches drawn from ``ids``."""
    rng = np.random.default_rng(seed)
    patches = rng.choice(np.asarray(ids), size=(-(-ny // 4), -(-nx // 4)))
    return np.kron(patches, np.ones((4, 4), dtype=int))[:ny, :nx].astype(dtype)


def render(table: ParameterTable, classes, sza, saa, vza, vaa, wavelengths=None, n_bands=None,
           brightness=None, dtype=np.float64) -> np.ndarray:
    """Reflectance cube (band, y, x) of a scene: ``brightness * f_class(geometry; p(band))``.

    Pixels whose class is not in ``table`` get ``brightness`` (a flat spectrum). Uses the public
    model call once per class and band (no shared geometry, no affine shortcuts).
    """
    classes = np.asarray(classes)
    sza, saa, vza, vaa = (np.asarray(a, dtype=np.float64) for a in (sza, saa, vza, vaa))
    resolved = table.for_bands(wavelengths, n_bands=n_bands)
    n_bands = len(wavelengths) if n_bands is None else n_bands
    brightness = np.ones(classes.shape) if brightness is None else np.asarray(brightness, float)
    phi = relative_azimuth(saa, vaa)
    cube = np.empty((n_bands, *classes.shape))
    cube[:] = brightness
    for class_id, entry in resolved.items():
        mask = classes == class_id
        for band in range(n_bands):
            params = {name: value[band] for name, value in entry.params.items()}
            cube[band][mask] = brightness[mask] * entry.model(sza[mask], vza[mask], phi[mask], **params)
    return cube.astype(dtype)


def synthetic_scene(ny: int = 24, nx: int = 32, wavelengths=(480.0, 560.0, 660.0, 830.0),
                    table: ParameterTable | None = None, seed: int = 0, dtype=np.float32,
                    angles: dict | None = None) -> dict[str, xr.DataArray]:
    """A georeferenced scene rendered from ``table`` (default :func:`example_table`).

    Returns DataArrays ``reflectance`` (band, y, x) with a ``wavelength`` coord, ``classes``,
    ``sza``, ``saa``, ``vza``, ``vaa`` (y, x) on the same grid, and ``brightness``.
    """
    table = example_table() if table is None else table
    rng = np.random.default_rng(seed)
    angles = synthetic_angles(ny, nx) if angles is None else angles
    classes = synthetic_classes(ny, nx, ids=table.class_ids, seed=seed)
    brightness = rng.uniform(0.5, 2.0, size=(ny, nx))
    cube = render(table, classes, **angles, wavelengths=list(wavelengths), brightness=brightness, dtype=dtype)
    band = np.arange(1, len(wavelengths) + 1)
    reflectance = xr.DataArray(
        cube, dims=("band", "y", "x"), name="reflectance",
        coords={"band": band, "wavelength": ("band", np.asarray(wavelengths, float))},
        attrs={"units": "1", "long_name": tuple(f"{wavelength_text(w)} nm" for w in wavelengths)},
    )
    scene = {"reflectance": georeference(reflectance)}
    scene["classes"] = georeference(xr.DataArray(classes, dims=("y", "x"), name="classes"))
    for name, value in angles.items():
        scene[name] = georeference(xr.DataArray(value, dims=("y", "x"), name=name, attrs={"units": "degree"}))
    scene["brightness"] = georeference(xr.DataArray(brightness, dims=("y", "x"), name="brightness"))
    return scene


def write_scene(directory: str | os.PathLike, scene: dict[str, xr.DataArray], blocksize: int = 16,
                class_nodata: int | None = 255) -> dict[str, Path]:
    """Write a scene as GeoTIFFs: ``image.tif`` (wavelengths in band descriptions), ``angles.tif``
    (4 bands sza, saa, vza, vaa), ``classes.tif`` (uint8, nodata ``class_nodata``)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    options = {"tiled": True, "blockxsize": blocksize, "blockysize": blocksize, "compress": "deflate"}
    paths = {"image": directory / "image.tif", "angles": directory / "angles.tif",
             "classes": directory / "classes.tif"}
    reflectance = scene["reflectance"].drop_vars("wavelength")
    reflectance.rio.write_nodata(np.nan, encoded=False, inplace=True)
    reflectance.rio.to_raster(paths["image"], **options)
    angles = xr.concat([scene[name] for name in ("sza", "saa", "vza", "vaa")], dim="band")
    angles = angles.assign_coords(band=[1, 2, 3, 4])
    angles.attrs = {"long_name": ("sza", "saa", "vza", "vaa"), "units": "degree"}
    angles.rio.write_nodata(np.nan, encoded=False, inplace=True)
    angles.rio.to_raster(paths["angles"], **options)
    classes = scene["classes"].copy()
    if class_nodata is not None:
        classes = classes.rio.write_nodata(class_nodata)
    classes.rio.to_raster(paths["classes"], **options)
    return paths


def write_scene_chain(directory: str | os.PathLike, text: str | None = None, **sections) -> Path:
    """A chain config ``chain.yaml`` beside the scene ``directory`` of :func:`write_scene` (with the
    parameter table ``params.yaml``): that one scene, outputs in ``chain_out`` beside it, one
    synchronous worker in chunks of 16 pixels; ``sections`` replace whole sections of it, and
    ``text`` is written as it is instead. Returns the path."""
    directory = Path(directory)
    path = directory.parent / "chain.yaml"
    if text is None:
        document = {
            "inputs": {"images": [f"{directory.name}/image.tif"],
                       "angles": {"kind": "geotiff", "path": "{dir}/angles.tif"}, "classes": "{dir}/classes.tif"},
            "parameters": {"table": f"{directory.name}/params.yaml"},
            "outputs": {"directory": "chain_out"},
            "engine": {"scheduler": "synchronous", "workers": 1, "chunk": 16},
            **sections,
        }
        text = yaml.safe_dump(document, sort_keys=False)
    path.write_text(text)
    return path


def file_digests(directory: str | os.PathLike) -> dict[str, str]:
    """SHA-256 of every regular file below ``directory``, by relative path: compare two calls to
    show that nothing was modified. ``is_file()`` is False for a FIFO, so none is ever opened."""
    directory = Path(directory)
    return {str(path.relative_to(directory)): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(directory.rglob("*")) if path.is_file()}
