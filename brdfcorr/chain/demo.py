"""The embedded demo: a realistic wide-field-of-view airborne line, corrected by a chain config.

The scene is a push-broom line flown north over a small town near Hamburg on a June morning:

* **geometry**: a flat-earth line scanner at ``altitude`` above ground with a ``fov`` (72 deg,
  +-36 deg) field of view; every column has its own view zenith ``atan(|d| / H)`` (d: across-track
  distance from the nadir track) and view azimuth (towards the sensor: 270 deg east of the track,
  90 deg west of it); the sun's zenith and azimuth per pixel come from the solar position (pvlib,
  :func:`brdfcorr.io.sensors.solar.solar_angles`) at :data:`DEMO_TIME`. With the sun in the east-south-
  east, pixels east of the track look into forward scattering (relative azimuth near 160 deg),
  those west of it into backscattering (near 20 deg). The specular roofs and concrete appear
  brighter in the east, the vegetation and soil (volume scattering and shadow hiding, brightest
  towards the hot spot) in the west: the across-track brightness gradients a BRDF normalization
  removes.
* **classes**: 1 roof tile and 2 concrete, with the Torrance-Sparrow fits of paper 003, Table 1
  (``roof_tile`` and ``blue_concrete``, 550 nm); 3 grass, 4 trees and 5 bare soil with the
  kernel-driven MODIS RTLSR model (``ross_thick_li_sparse``) and **illustrative** weights per
  wavelength (:data:`GRASS_ILLUSTRATIVE`, :data:`TREES_ILLUSTRATIVE`, :data:`SOIL_ILLUSTRATIVE`;
  not a published fit); 0 for water (no class, left unchanged).
* **bands**: six bands 450-860 nm; each class has a reflectance spectrum (:data:`SPECTRA`), a
  smooth texture and 0.3 % sensor noise.

The image is rendered as ``R(band) = pi * f_class(sun, view; p) * spectrum_class(band) * texture``
with brdfcorr's public model functions, so a correction with the same parameters to a reference
geometry must give ``pi * f_class(reference) * spectrum * texture``: the gradient disappears.

:func:`run_demo` writes the scene as GeoTIFFs, runs the chain ``configs/demo.yaml`` on it
(corrected GeoTIFF, QA raster, assessment report and profile figure, before/after quicklook, run
report) and the material-library figure.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr
from scipy.ndimage import gaussian_filter

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import run_chain
from brdfcorr.errors import InputError
from brdfcorr.io.files import atomic_path
from brdfcorr.io.sensors.solar import solar_angles
from brdfcorr.io.writer import local_scheduler
from brdfcorr.models.materials import load_material, material_names
from brdfcorr.params import ClassEntry, ParameterTable
from brdfcorr.plot.materials import plot_materials
from brdfcorr.testing import render

__all__ = [
    "DEMO_TIME",
    "WAVELENGTHS",
    "GRASS_ILLUSTRATIVE",
    "TREES_ILLUSTRATIVE",
    "SOIL_ILLUSTRATIVE",
    "KERNEL_CLASSES",
    "SPECTRA",
    "demo_table",
    "demo_angles",
    "demo_classes",
    "demo_scene",
    "write_demo_scene",
    "default_config",
    "run_demo",
    "DemoResult",
]

#: Acquisition time (UTC): a June morning, sun in the east-south-east.
DEMO_TIME = "2026-06-15T08:00:00+00:00"
#: Lower-left corner of the line, UTM zone 32N (near Hamburg, 53.55 N 10.0 E) [m].
DEMO_ORIGIN = (566_000.0, 5_933_000.0)
DEMO_CRS = "EPSG:32632"
#: Band centres [nm].
WAVELENGTHS = (450.0, 500.0, 560.0, 660.0, 740.0, 860.0)

#: Class ids of the demo class map.
ROOF_TILE, CONCRETE, GRASS, TREES, SOIL = 1, 2, 3, 4, 5

# Illustrative kernel weights of the MODIS RTLSR model (Ross-Thick Li-Sparse-Reciprocal,
# ``ross_thick_li_sparse``): NOT published fits. f_iso [sr^-1] is the nadir-sun nadir-view
# reflectance factor of a typical spectrum divided by pi; f_vol and f_geo are fixed fractions of it
# in the range of MODIS MCD43A1 weights of such covers (per wavelength, interpolated to the bands).
_KERNEL_WAVELENGTHS = [450.0, 550.0, 650.0, 700.0, 750.0, 900.0]


def _kernel_class(class_id: int, name: str, **weights: list[float]) -> dict:
    """A table entry of the RTLSR model with weights [sr^-1] at :data:`_KERNEL_WAVELENGTHS`."""
    return {"id": class_id, "name": name, "model": "ross_thick_li_sparse", "wavelengths": _KERNEL_WAVELENGTHS,
            "params": weights}


#: Grass (lawn): R = pi f_iso of 3 % blue, 8 % green, 4 % red, 40-45 % near infrared; volume
#: scattering f_vol / f_iso 0.6 (visible) to 0.8 (NIR), shadowing f_geo / f_iso 0.2 to 0.12.
GRASS_ILLUSTRATIVE = _kernel_class(
    GRASS, "grass_illustrative",
    f_iso=[0.0095, 0.0255, 0.0127, 0.0320, 0.1270, 0.1430],
    f_vol=[0.0057, 0.0153, 0.0076, 0.0208, 0.1016, 0.1144],
    f_geo=[0.0019, 0.0051, 0.0025, 0.0054, 0.0152, 0.0172],
)
#: Trees (deciduous crowns): darker than grass (2.5 % blue, 5.5 % green, 3 % red, 30-33 % NIR),
#: less volume scattering (f_vol / f_iso 0.5 to 0.6) and more crown shadowing (f_geo / f_iso 0.25
#: to 0.18).
TREES_ILLUSTRATIVE = _kernel_class(
    TREES, "trees_illustrative",
    f_iso=[0.0080, 0.0175, 0.0095, 0.0223, 0.0955, 0.1050],
    f_vol=[0.0040, 0.0088, 0.0048, 0.0123, 0.0573, 0.0630],
    f_geo=[0.0020, 0.0044, 0.0024, 0.0047, 0.0172, 0.0189],
)
#: Bare soil (dry loam): reflectance rising from 10 % (450 nm) to 26 % (900 nm), little volume
#: scattering (f_vol / f_iso 0.1) and rough-surface shadowing (f_geo / f_iso 0.3).
SOIL_ILLUSTRATIVE = _kernel_class(
    SOIL, "bare_soil_illustrative",
    f_iso=[0.0318, 0.0446, 0.0573, 0.0637, 0.0700, 0.0828],
    f_vol=[0.0032, 0.0045, 0.0057, 0.0064, 0.0070, 0.0083],
    f_geo=[0.0095, 0.0134, 0.0172, 0.0191, 0.0210, 0.0248],
)
#: The kernel-driven classes, in class-id order.
KERNEL_CLASSES = (GRASS_ILLUSTRATIVE, TREES_ILLUSTRATIVE, SOIL_ILLUSTRATIVE)

#: Relative reflectance spectra of the Table-1 classes at :data:`WAVELENGTHS` (1 at 560 nm, the
#: band nearest the 550 nm of the fits); illustrative shapes (red clay tile, grey concrete). The
#: kernel classes take their spectra from their spectral parameters, so their factor is 1.
SPECTRA = {
    ROOF_TILE: (0.55, 0.65, 1.0, 1.9, 2.2, 2.3),
    CONCRETE: (0.90, 0.95, 1.0, 1.03, 1.05, 1.07),
    **{entry["id"]: (1.0,) * 6 for entry in KERNEL_CLASSES},
}


def demo_table() -> ParameterTable:
    """The demo's parameter table: roof tile and concrete from paper 003 Table 1 (built-in
    ``roof_tile`` and ``blue_concrete``), grass, trees and bare soil from :data:`KERNEL_CLASSES`."""

    entries = []
    for class_id, name in ((ROOF_TILE, "roof_tile"), (CONCRETE, "blue_concrete")):
        material = load_material(name)
        entries.append(ClassEntry(id=class_id, name=material.name, model=material.model.name,
                                  params=dict(material.params)))
    entries.extend(ClassEntry(**entry) for entry in KERNEL_CLASSES)
    return ParameterTable(classes=entries)


def _grid(rows: int, columns: int, pixel: float) -> xr.DataArray:
    """An empty (y, x) template on the demo grid (north up; CRS and transform)."""

    x = DEMO_ORIGIN[0] + pixel * (np.arange(columns) + 0.5)
    y = DEMO_ORIGIN[1] + pixel * rows - pixel * (np.arange(rows) + 0.5)
    template = xr.DataArray(np.zeros((rows, columns), np.float32), dims=("y", "x"), coords={"x": x, "y": y})
    return template.rio.write_crs(DEMO_CRS).rio.write_transform(template.rio.transform(recalc=True))


def demo_angles(rows: int = 300, pixel: float = 3.0, altitude: float = 1000.0, fov: float = 72.0,
                time: str = DEMO_TIME) -> xr.Dataset:
    """Sun and view angles [deg] of the demo line (``docs/conventions.md`` conventions), georeferenced.

    Parameters
    ----------
    rows : int
        Number of lines (along track, north).
    pixel : float
        Ground pixel size [m]; the swath ``2 H tan(fov / 2)`` fixes the number of columns.
    altitude : float
        Flying height above ground H [m].
    fov : float
        Full across-track field of view [deg].
    time : str
        Acquisition time (ISO 8601, with time zone).

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` (y, x) float32 [deg], numpy-backed.
    """

    if not 0 < fov < 180:
        raise InputError(f"fov = {fov:g} deg must be in (0, 180)")
    swath = 2.0 * altitude * np.tan(np.radians(fov / 2.0))
    columns = max(3, int(round(swath / pixel)))
    template = _grid(rows, columns, pixel)
    across = pixel * (np.arange(columns) + 0.5) - swath / 2.0  # [m], east positive
    vza = np.degrees(np.arctan(np.abs(across) / altitude))
    vaa = np.where(across > 0, 270.0, 90.0)  # towards the sensor, which flies along the centre
    sun = solar_angles(time, template).compute(scheduler=local_scheduler(None))  # without dask.distributed
    angles = xr.Dataset(coords=template.coords)
    for name, values in (("sza", sun["sza"].values), ("saa", sun["saa"].values),
                         ("vza", np.broadcast_to(vza, (rows, columns))),
                         ("vaa", np.broadcast_to(vaa, (rows, columns)))):
        angles[name] = (("y", "x"), np.ascontiguousarray(values, dtype=np.float32), {"units": "degree"})
    return angles


def demo_classes(rows: int, columns: int, pixel: float, seed: int = 0) -> np.ndarray:
    """A town-like class map: grass with a concrete street grid, tiled-roof houses in the blocks,
    concrete yards, groups of trees and patches of bare soil in the open ground, and a pond
    (class 0, no class). Sizes in metres scaled by ``pixel`` [m]."""

    rng = np.random.default_rng(seed)
    classes = np.full((rows, columns), GRASS, dtype=np.uint8)
    cell = lambda metres: max(1, int(round(metres / pixel)))  # noqa: E731
    block, street = cell(90.0), cell(9.0)
    for start in range(block // 2, rows, block):
        classes[start:start + street, :] = CONCRETE
    for start in range(block // 3, columns, block):
        classes[:, start:start + street] = CONCRETE
    for top in range(0, rows, block):
        for left in range(0, columns, block):
            for _ in range(rng.integers(2, 6)):
                height, width = cell(rng.uniform(10, 24)), cell(rng.uniform(10, 24))
                y0 = top + street + rng.integers(0, max(1, block - street - height))
                x0 = left + street + rng.integers(0, max(1, block - street - width))
                if rng.uniform() < 0.75:
                    classes[y0:y0 + height, x0:x0 + width] = ROOF_TILE
                else:
                    classes[y0:y0 + height, x0:x0 + width] = CONCRETE
    # Trees and bare soil replace grass where a smooth random field (~25 m patches) is high or low.
    field = gaussian_filter(np.random.default_rng(seed + 2).standard_normal((rows, columns)), sigma=cell(12.0))
    field = (field - field.mean()) / field.std()
    open_ground = classes == GRASS
    classes[open_ground & (field > 0.8)] = TREES
    classes[open_ground & (field < -1.1)] = SOIL
    yy, xx = np.mgrid[:rows, :columns]
    centre = (rows * 0.7, columns * 0.2)
    radius = cell(40.0)
    classes[(yy - centre[0]) ** 2 + (xx - centre[1]) ** 2 < radius**2] = 0  # a pond: no class
    return classes


def demo_scene(rows: int = 300, pixel: float = 3.0, altitude: float = 1000.0, fov: float = 72.0,
               time: str = DEMO_TIME, seed: int = 0, noise: float = 0.003) -> xr.Dataset:
    """The demo scene: ``reflectance`` (band, y, x) with a ``wavelength`` coordinate [nm],
    ``classes`` (y, x) and the four angles [deg], georeferenced (UTM 32N).

    See the module docstring for the scene; :func:`demo_angles` for the parameters. ``noise`` is
    the relative standard deviation of the sensor noise [-].
    """


    angles = demo_angles(rows, pixel, altitude, fov, time)
    rows, columns = angles.sizes["y"], angles.sizes["x"]
    classes = demo_classes(rows, columns, pixel, seed)
    rng = np.random.default_rng(seed + 1)
    texture = 1.0 + 0.25 * gaussian_filter(rng.standard_normal((rows, columns)), sigma=2.0)
    table = demo_table()
    cube = render(table, classes, *(angles[name].values for name in ("sza", "saa", "vza", "vaa")),
                  wavelengths=list(WAVELENGTHS), brightness=np.pi * texture)
    for class_id, spectrum in SPECTRA.items():
        cube[:, classes == class_id] *= np.asarray(spectrum)[:, None]
    water = classes == 0
    cube[:, water] = np.array([0.04, 0.04, 0.035, 0.02, 0.01, 0.008])[:, None]  # dark water, no BRDF model
    cube *= 1.0 + noise * rng.standard_normal(cube.shape)
    band = np.arange(1, len(WAVELENGTHS) + 1)
    reflectance = xr.DataArray(
        cube.astype(np.float32), dims=("band", "y", "x"), name="reflectance",
        coords={"band": band, "wavelength": ("band", np.asarray(WAVELENGTHS), {"units": "nm"}),
                **angles.coords},
        attrs={"units": "1", "long_name": tuple(f"{w:g} nm" for w in WAVELENGTHS)},
    )
    scene = angles.copy()
    scene["reflectance"] = reflectance
    scene["classes"] = (("y", "x"), classes, {"long_name": "land cover class",
                                              "flag_values": [0, 1, 2, 3, 4, 5],
                                              "flag_meanings": "water roof_tile concrete grass_illustrative "
                                                               "trees_illustrative bare_soil_illustrative"})
    scene.attrs = {"title": "brdfcorr demo: wide field of view airborne line", "time": time,
                   "altitude_m": altitude, "fov_deg": fov, "pixel_m": pixel}
    return scene


def write_demo_scene(directory: str | os.PathLike, scene: xr.Dataset, name: str = "line01") -> dict[str, Path]:
    """Write the scene as GeoTIFFs ``{name}_image.tif`` (wavelengths in band descriptions),
    ``{name}_angles.tif`` (sza, saa, vza, vaa) and ``{name}_classes.tif`` (uint8, nodata 255),
    each atomically."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    options = {"driver": "GTiff", "tiled": True, "blockxsize": 256, "blockysize": 256, "compress": "deflate"}
    image = scene["reflectance"].drop_vars("wavelength").rio.write_nodata(np.nan, encoded=False)
    angles = xr.concat([scene[key] for key in ("sza", "saa", "vza", "vaa")], dim="band")
    angles = angles.assign_coords(band=[1, 2, 3, 4]).rio.write_nodata(np.nan, encoded=False)
    angles.attrs = {"long_name": ("sza", "saa", "vza", "vaa"), "units": "degree"}
    classes = scene["classes"].astype(np.uint8).rio.write_nodata(255)
    classes.attrs = {"long_name": "land cover class"}
    paths = {}
    for role, array in (("image", image), ("angles", angles), ("classes", classes)):
        target = directory / f"{name}_{role}.tif"
        array = array.rio.write_crs(DEMO_CRS)
        with atomic_path(target) as temporary:
            array.rio.to_raster(temporary, **options)
        paths[role] = target
    return paths


def default_config() -> Path:
    """The demo chain shipped in the package, ``brdfcorr/data/demo.yaml``.

    It is a copy of the documented ``configs/demo.yaml`` of the repository (a test keeps the two
    identical), read through :mod:`importlib.resources` so that an installed brdfcorr finds it.
    """
    resource = files("brdfcorr").joinpath("data/demo.yaml")
    if not isinstance(resource, Path) or not resource.is_file():
        raise InputError(f"the demo chain {resource} is not there (brdfcorr is installed without its data files); "
                         "give the chain config explicitly (brdfcorr demo --config CHAIN.yaml)")
    return resource


@dataclass
class DemoResult:
    """What :func:`run_demo` wrote: the scene's inputs, the chain's report, extra figures."""

    inputs: dict[str, Path]
    config: Path
    report: object  # brdfcorr.chain.run.RunReport
    figures: list[Path]


def run_demo(output_dir: str | os.PathLike = "demo_output", config: str | os.PathLike | None = None, *,
             rows: int = 300, pixel: float = 3.0, materials_figure: bool = True, progress=None,
             overrides: dict | None = None) -> DemoResult:
    """Build the demo scene, run the demo chain on it and write its outputs under ``output_dir``.

    The chain config (default ``configs/demo.yaml``) is copied to ``output_dir/demo.yaml`` and run
    from there (its relative paths point into ``output_dir``), so the run can be repeated with
    ``brdfcorr run output_dir/demo.yaml``. The scene is rewritten every time and the chain redoes
    every output (``outputs.existing: overwrite``).

    Parameters
    ----------
    output_dir : path-like
    config : path-like, optional
        Chain config to run instead of ``configs/demo.yaml``.
    rows, pixel :
        Scene size: lines, and ground pixel size [m] (see :func:`demo_angles`).
    materials_figure : bool
        Also write ``materials_brdf.png``, the BRDFs of the material library.
    progress : callable, optional
        Passed to :func:`brdfcorr.chain.run.run_chain`.
    overrides : dict, optional
        Dotted config keys to override (:func:`brdfcorr.chain.config.apply_overrides`).
    """

    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    source = Path(config) if config is not None else default_config()
    chain = output_dir / "demo.yaml"
    if source.resolve() != chain.resolve():
        with atomic_path(chain) as temporary:
            shutil.copyfile(source, temporary)
    settings = load_config(chain, {"outputs.existing": "overwrite", **(overrides or {})})
    inputs = write_demo_scene(output_dir / "scene", demo_scene(rows=rows, pixel=pixel))
    report = run_chain(settings, progress=progress)
    figures = [Path(path) for result in report.scenes for key, path in result.get("outputs", {}).items()
               if key in ("assess_profiles", "quicklook")]
    if materials_figure:

        target = output_dir / "materials_brdf.png"
        with atomic_path(target) as temporary:
            plot_materials([load_material(name) for name in material_names()]).savefig(temporary, dpi=90, format="png")
        figures.append(target)
    return DemoResult(inputs, chain, report, figures)
